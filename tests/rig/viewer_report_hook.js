  // The relighting page's test hook, for tests/rig/view_command_test.cc only: the test puts it
  // into its own copy of viewer.js (inside the page's closure, where the page marks it, before
  // anything can fail); the
  // published page has no such hook (it sent the rendered pixels and the page's address to
  // any URL named in ?report=).
  // ?report=URL&shots=x,y,z|x,y,z...: each shot's pixels POSTed to URL (raw RGBA,
  // rows top-down), then URL/done with the resources the page loaded; when the first view
  // rejects, URL/done with {failed: its reason} at once.
  const report = params.get('report');
  if (report) {
    (async () => {
      let firstMs, fullMs;
      try {
        firstMs = await window.rigFirstView;
        fullMs = await window.rigFullView;
      } catch (e) {
        await fetch(report + '/done', { method: 'POST', mode: 'no-cors',
                                        body: JSON.stringify({ failed: String(e.message || e), message: message.textContent }) });
        return;
      }
      const shots = (params.get('shots') || '').split('|').filter((s) => s);
      const send = (path, body) => fetch(report + path, { method: 'POST', body, mode: 'no-cors' });
      for (let i = 0; i < Math.max(1, shots.length); ++i) {
        if (shots.length) { lamps = parseLamps(shots[i]); uploadLamps(); }
        await whenDrawn();
        const w = canvas.width, h = canvas.height, px = new Uint8Array(w * h * 4), flip = new Uint8Array(w * h * 4);
        gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
        for (let y = 0; y < h; ++y) flip.set(px.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
        await send(`/shot?i=${i}&w=${w}&h=${h}`, flip);
      }
      const resources = performance.getEntriesByType('resource').map((e) => e.name);
      await send('/done', JSON.stringify({ first_view_ms: firstMs, full_view_ms: fullMs, resources, location: location.href,
                                           renderer: gl.getParameter(gl.RENDERER), message: message.textContent }));
    })();
  }
