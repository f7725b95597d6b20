// rig's relighting page: a model in relight's web format (info.json + plane_N.jpg, optionally
// deep-zoom tiles plane_N.dzi + plane_N_files/L/x_y.jpg), relit in a WebGL2 fragment shader.
// The light weights follow the reconstruction formulas of relight's renderer (see
// docs/viewer.md); the display follows `rig render`'s default for the model.
'use strict';
(function () {
  const D = window.RIG_VIEW;
  const info = D.info;
  const params = new URLSearchParams(location.search);
  const canvas = document.getElementById('view');
  const message = document.getElementById('message');
  // window.rigFirstView / window.rigFullView: the time (ms after navigation) of the first whole
  // picture / of every tile of the level the view needs; both reject, with the reason, when the
  // page fails instead (a model it cannot show, no WebGL2, a plane or tile that does not load).
  const viewEnds = [];
  const viewPromise = () => {
    const p = new Promise((resolve, reject) => viewEnds.push({ resolve, reject }));
    p.catch(() => {});  // a failure is shown in the panel; a caller that awaits it sees it too
    return p;
  };
  window.rigFirstView = viewPromise();
  window.rigFullView = viewPromise();
  let failed = null;
  const failView = (text) => {
    if (failed === null) failed = text;
    message.textContent = failed;
    for (const e of viewEnds) e.reject(new Error(failed));
  };
  const fail = (text) => { failView(text); throw new Error(text); };
  window.addEventListener('error', (e) => failView(String((e.error && e.error.message) || e.message)));
  window.addEventListener('unhandledrejection', (e) => failView(String((e.reason && e.reason.message) || e.reason)));
  // (the test hook goes here: tests/rig/view_command_test.cc)
  if (params.get('ui') === '0') document.body.classList.add('bare');

  const gl = canvas.getContext('webgl2', { preserveDrawingBuffer: true, antialias: false,
                                           premultipliedAlpha: false, alpha: false });
  if (!gl) fail('This page needs WebGL2.');

  // ---- The model: how the planes combine -------------------------------------------------
  const W = info.width, H = info.height;
  const type = info.type, colorspace = info.colorspace;
  const ycc = colorspace === 'mycc' ? info.yccplanes : null;  // [ny, nc, nc]
  if (colorspace === 'mycc' && (!Array.isArray(ycc) || ycc.length !== 3)) fail('info.json: mycc needs yccplanes [ny, nc, nc]');
  const nplanes = ycc ? ycc[0] + ycc[1] + ycc[2] : info.nplanes;
  const nfiles = Math.ceil(nplanes / 3);
  const material = info.materials[0];
  const scale = material.scale, bias = material.bias;
  const lrgb = colorspace === 'lrgb';
  if (!['ptm', 'hsh', 'sh', 'bilinear', 'rbf'].includes(type)) fail('Type "' + type + '" is not shown here.');
  if (!['rgb', 'lrgb', 'mrgb', 'mycc'].includes(colorspace)) fail('Colorspace "' + colorspace + '" is not shown here.');
  const pca = colorspace === 'mrgb' || colorspace === 'mycc';
  if (nfiles > 15) fail(nplanes + ' planes: at most 45 are shown here.');
  const terms = lrgb ? 6 : (colorspace === 'rgb' ? nplanes / 3 : 0);

  function unit(l) {
    const n = Math.hypot(l[0], l[1], l[2]);
    return n > 0 ? [l[0] / n, l[1] / n, l[2] / n] : [0, 0, 1];
  }

  // relight's light weights of the rgb/lrgb bases (Rti::lightWeightsPtm/Hsh/Sh).
  function weights(d) {
    const lx = d[0], ly = d[1];
    if (type === 'ptm') return [1, lx, ly, lx * lx, lx * ly, ly * ly];
    const lz = Math.sqrt(Math.max(0, 1 - lx * lx - ly * ly));
    let phi = Math.atan2(ly, lx);
    if (phi < 0) phi += 2 * Math.PI;
    if (type === 'hsh') {
      const theta = Math.min(Math.acos(Math.min(1, lz)), Math.PI / 2 - 0.01);
      const ct = Math.cos(theta), s = Math.sqrt(Math.max(0, ct - ct * ct)), P = Math.PI;
      const w = [1 / Math.sqrt(2 * P), Math.sqrt(6 / P) * Math.cos(phi) * s,
                 Math.sqrt(3 / (2 * P)) * (2 * ct - 1), Math.sqrt(6 / P) * Math.sin(phi) * s];
      if (terms <= 4) return w.slice(0, terms);
      return w.concat([Math.sqrt(30 / P) * Math.cos(2 * phi) * (ct * ct - ct),
                       Math.sqrt(30 / P) * Math.cos(phi) * (2 * ct - 1) * s,
                       Math.sqrt(5 / (2 * P)) * (1 - 6 * ct + 6 * ct * ct),
                       Math.sqrt(30 / P) * Math.sin(phi) * (2 * ct - 1) * s,
                       Math.sqrt(30 / P) * Math.sin(2 * phi) * (ct * ct - ct)]);
    }
    // sh: real spherical harmonics of degree <= 2
    const theta = Math.acos(Math.min(1, lz));
    const sT = Math.sin(theta), cT = Math.cos(theta), sP = Math.sin(phi), cP = Math.cos(phi);
    const P = Math.PI;
    return [0.5 / Math.sqrt(P), 0.5 * Math.sqrt(3 / P) * sP * sT, 0.5 * Math.sqrt(3 / P) * cT,
            0.5 * Math.sqrt(3 / P) * cP * sT, 0.25 * Math.sqrt(15 / P) * Math.sin(2 * phi) * sT * sT,
            0.5 * Math.sqrt(15 / P) * sT * cT * sP, 0.25 * Math.sqrt(5 / P) * (3 * cT * cT - 1),
            0.5 * Math.sqrt(15 / P) * sT * cT * cP, 0.25 * Math.sqrt(15 / P) * sT * sT * Math.cos(2 * phi)]
        .slice(0, terms);
  }

  // The basis of an mrgb/mycc model, held at the nodes of an octahedral grid (bilinear) or at
  // the fitted lights (rbf): the (nplanes + 1) x 3 values at d.
  let gridValues = null;
  const rbfLights = [];
  let nodes = 0;
  if (pca) {
    if (type !== 'bilinear' && type !== 'rbf') fail(colorspace + ' of type "' + type + '" is not shown here (bilinear, rbf).');
    if (type === 'rbf') {
      const l = info.lights || [];
      for (let i = 0; i + 2 < l.length; i += 3) rbfLights.push([l[i], l[i + 1], l[i + 2]]);
      if (!rbfLights.length || !(info.sigma > 0)) fail('info.json: rbf needs lights and sigma');
      nodes = rbfLights.length;
    } else {
      nodes = info.resolution * info.resolution;
    }
    const stored = info.basis, range = material.range;
    if (!stored || !range || stored.length !== (nplanes + 1) * nodes * 3) fail('info.json: basis does not match the planes and the ' + (type === 'rbf' ? 'lights' : 'resolution'));
    gridValues = stored.map((v, i) => {
      const p = Math.floor(i / (nodes * 3));
      return p === 0 ? v : (v - 127) / range[p - 1];
    });
  }
  // relight's rbf weights (Rti::lightWeightsRbf): exp(-|l - L_i|^2 / sigma^2) normalised, those
  // at or below 0.001 dropped, normalised again; l's z from its x and y as relight's renderer.
  function rbfAt(d) {
    const lx = d[0], ly = d[1], lz = Math.sqrt(Math.max(0, 1 - lx * lx - ly * ly));
    const radius = 1 / (info.sigma * info.sigma);
    const w = rbfLights.map((L) => Math.exp(-radius * ((lx - L[0]) ** 2 + (ly - L[1]) ** 2 + (lz - L[2]) ** 2)));
    const total = w.reduce((a, b) => a + b, 0);
    const kept = [];
    let sum = 0;
    w.forEach((v, i) => { const n = total > 0 ? v / total : 0; if (n > 0.001) { kept.push([i, n]); sum += n; } });
    const out = new Float64Array((nplanes + 1) * 3);
    for (let p = 0; p <= nplanes; ++p)
      for (let c = 0; c < 3; ++c) {
        let acc = 0;
        for (const [i, n] of kept) acc += (n / sum) * gridValues[(p * nodes + i) * 3 + c];
        out[p * 3 + c] = acc;
      }
    return out;
  }
  // mycc: plane p < 3 nc feeds its own channel p mod 3 of (Y, Co, Cg), a later one Y alone; then
  // YCoCg -> RGB (relight's Color3::toRgb), folded into the values as it is linear.
  function yccToRgb(g) {
    const interleaved = 3 * ycc[1];
    for (let p = 0; p < nplanes; ++p)
      for (let c = 0; c < 3; ++c)
        if (!(p < interleaved ? c === p % 3 : c === 0)) g[(p + 1) * 3 + c] = 0;
    for (let p = 0; p <= nplanes; ++p) {
      const y = g[p * 3], co = g[p * 3 + 1], cg = g[p * 3 + 2];
      g[p * 3] = y + co / 2 - cg / 2;
      g[p * 3 + 1] = y + cg / 2;
      g[p * 3 + 2] = y - co / 2 - cg / 2;
    }
    return g;
  }
  function basisAt(d) {
    const g = type === 'rbf' ? rbfAt(d) : gridAt(d);
    return ycc ? yccToRgb(g) : g;
  }
  function gridAt(d) {
    const res = info.resolution;
    const s = Math.abs(d[0]) + Math.abs(d[1]) + Math.abs(d[2]);
    const x = (d[0] + d[1]) / s, y = (d[1] - d[0]) / s;
    const u = (x + 1) / 2 * (res - 1), v = (y + 1) / 2 * (res - 1);
    const sx = Math.min(Math.max(Math.floor(u), 0), res - 2), sy = Math.min(Math.max(Math.floor(v), 0), res - 2);
    const dx = u - sx, dy = v - sy;
    const nodes = [sx + sy * res, sx + 1 + sy * res, sx + (sy + 1) * res, sx + 1 + (sy + 1) * res];
    const w = [(1 - dx) * (1 - dy), dx * (1 - dy), (1 - dx) * dy, dx * dy];
    const out = new Float64Array((nplanes + 1) * 3);
    for (let p = 0; p <= nplanes; ++p)
      for (let c = 0; c < 3; ++c) {
        let acc = 0;
        for (let i = 0; i < 4; ++i) acc += w[i] * gridValues[(p * res * res + nodes[i]) * 3 + c];
        out[p * 3 + c] = acc;
      }
    return out;
  }

  // One lamp as 3 matrix rows per plane file plus an offset: value/255 = B + sum_j M_j T_j,
  // T_j the texels of plane_j.jpg in 0..1 (lrgb: L = B + sum_{j>=1} M_j T_j, value = L T_0).
  function lampMatrices(dir) {
    const d = unit(dir);
    const m = new Float32Array((3 * nfiles + 1) * 4);
    const B = [0, 0, 0];
    const set = (j, row, col, v) => { m[(3 * j + row) * 4 + col] = v; };
    if (pca) {
      const g = basisAt(d);
      for (let k = 0; k < 3; ++k) B[k] = g[k] / 255;
      for (let p = 0; p < nplanes; ++p)
        for (let k = 0; k < 3; ++k) {
          const v = scale[p] * g[(p + 1) * 3 + k];
          set(Math.floor(p / 3), k, p % 3, v);
          B[k] -= bias[p] * v;
        }
    } else if (lrgb) {
      const w = weights(d);
      for (let p = 3; p < 9; ++p) {
        const v = w[p - 3] * scale[p];
        for (let k = 0; k < 3; ++k) { set(Math.floor(p / 3), k, p % 3, v); B[k] -= bias[p] * v; }
      }
    } else {
      const w = weights(d);
      for (let p = 0; p < nplanes; ++p) {
        const j = Math.floor(p / 3), c = p % 3, v = w[j] * scale[p];
        set(j, c, c, v);
        B[c] -= bias[p] * v;
      }
    }
    const o = 3 * nfiles * 4;
    m[o] = B[0]; m[o + 1] = B[1]; m[o + 2] = B[2];
    return m;
  }

  // ---- Display -------------------------------------------------------------------------------
  const display = D.display || { encoding: 'srgb' };
  const hdr = display.encoding === 'linear';
  const note = document.getElementById('display-note');
  note.textContent = hdr
    ? 'HDR model: rho = decode(value)/' + display.gain.toPrecision(4) + ', Ward\'s curve of the default light (a LUT from rig view)'
    : 'sRGB model: shown in the photographs\' encoding, as rig render';

  // ---- Shaders -------------------------------------------------------------------------------
  const MAX_LAMPS = 8;
  const vs = `#version 300 es
uniform vec4 uRect;  // clip-space x0, y0, x1, y1
uniform vec4 uTex;   // texture u0, v0, u1, v1
out vec2 vUv;
void main() {
  vec2 c = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
  vUv = mix(uTex.xy, uTex.zw, c);
  gl_Position = vec4(mix(uRect.xy, uRect.zw, c), 0.0, 1.0);
}`;
  let samplers = '', fetches = '';
  for (let j = 0; j < nfiles; ++j) {
    samplers += `uniform sampler2D uPlane${j};\n`;
    fetches += `  vec4 t${j} = texture(uPlane${j}, vUv);\n`;
  }
  let sum = '';
  for (let j = lrgb ? 1 : 0; j < nfiles; ++j) {
    sum += `    v += vec3(dot(texelFetch(uLamps, ivec2(${3 * j}, l), 0).xyz, t${j}.xyz),
              dot(texelFetch(uLamps, ivec2(${3 * j + 1}, l), 0).xyz, t${j}.xyz),
              dot(texelFetch(uLamps, ivec2(${3 * j + 2}, l), 0).xyz, t${j}.xyz));\n`;
  }
  if (lrgb) sum += '    v *= t0.xyz;\n';
  const fs = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
${samplers}uniform sampler2D uLamps;  // RGBA32F: row = lamp, 3 texels per plane file + the offset
uniform vec3 uColor[${MAX_LAMPS}];
uniform int uLampCount;
uniform float uExposure;
uniform vec3 uInvGain;  // HDR: the capture lamp's radiance / the gain the planes were encoded with
uniform int uMode;  // 0 relit, 1 plain image (normals / albedo)
uniform sampler2D uImage, uLut;
uniform vec2 uLutRange;  // ln luminance at the LUT's ends
uniform vec3 uLuma;      // luminance weights (R, G, B) rig render weighs with
uniform int uHdr;
in vec2 vUv;
out vec4 outColor;
vec3 decode(vec3 y) {
  vec3 a = abs(y);
  vec3 l = mix(pow((a + 0.055) / 1.055, vec3(2.4)), a / 12.92, vec3(lessThanEqual(a, vec3(0.04045))));
  return sign(y) * l;
}
vec3 encode(vec3 x) {
  vec3 a = abs(x);
  vec3 e = mix(1.055 * pow(a, vec3(1.0 / 2.4)) - 0.055, 12.92 * a, vec3(lessThanEqual(a, vec3(0.0031308))));
  return sign(x) * e;
}
void main() {
  if (uMode == 1) { outColor = vec4(texture(uImage, vUv).rgb, 1.0); return; }
${fetches}  vec3 rad = vec3(0.0);
  for (int l = 0; l < ${MAX_LAMPS}; ++l) {
    if (l >= uLampCount) break;
    vec3 v = texelFetch(uLamps, ivec2(${3 * nfiles}, l), 0).xyz;
${sum}    rad += decode(v) * uColor[l];
  }
  rad *= uExposure;
  vec3 outc;
  if (uHdr == 1) {
    rad *= uInvGain;
    // Ward's global curve as rig view computed it: display luminance (encoded) from ln Lw.
    float lw = dot(rad, uLuma);
    if (lw <= 0.0) { outc = vec3(0.0); }
    else {
      float u = clamp((log(lw) - uLutRange.x) / (uLutRange.y - uLutRange.x), 0.0, 1.0);
      float ld = texture(uLut, vec2(u, 0.5)).r;  // display luminance, linear 0..1
      outc = encode(clamp(rad * (ld / lw), 0.0, 1.0));
    }
  } else {
    outc = encode(rad);
  }
  outColor = vec4(clamp(outc, 0.0, 1.0), 1.0);
}`;
  function compile(kind, src) {
    const s = gl.createShader(kind);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) fail('shader: ' + gl.getShaderInfoLog(s));
    return s;
  }
  const prog = gl.createProgram();
  gl.attachShader(prog, compile(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) fail('link: ' + gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  const U = (n) => gl.getUniformLocation(prog, n);
  for (let j = 0; j < nfiles; ++j) gl.uniform1i(U('uPlane' + j), j);
  gl.uniform1i(U('uLamps'), 15);
  gl.uniform1i(U('uImage'), 14);
  gl.uniform1i(U('uLut'), 13);
  gl.bindVertexArray(gl.createVertexArray());
  gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
  gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);

  const lampTex = gl.createTexture();
  function uploadLamps() {
    const cols = 3 * nfiles + 1;
    const data = new Float32Array(cols * 4 * MAX_LAMPS);
    const colors = new Float32Array(3 * MAX_LAMPS);
    lamps.forEach((lamp, i) => {
      data.set(lampMatrices(lamp.dir), i * cols * 4);
      for (let k = 0; k < 3; ++k) colors[3 * i + k] = lamp.color[k] * lamp.intensity;
    });
    gl.activeTexture(gl.TEXTURE15);
    gl.bindTexture(gl.TEXTURE_2D, lampTex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, cols, MAX_LAMPS, 0, gl.RGBA, gl.FLOAT, data);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.uniform3fv(U('uColor'), colors);
    gl.uniform1i(U('uLampCount'), lamps.length);
  }
  if (hdr) {
    const lut = new Float32Array(display.lut);
    const t = gl.createTexture();
    gl.activeTexture(gl.TEXTURE13);
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.R32F, lut.length, 1, 0, gl.RED, gl.FLOAT, lut);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.uniform2f(U('uLutRange'), display.lut_log_min, display.lut_log_max);
    const w = display.luminance_rgb || [0.2126, 0.7152, 0.0722];
    gl.uniform3f(U('uLuma'), w[0], w[1], w[2]);
    gl.uniform1i(U('uHdr'), 1);
    const e = display.lamp_rgb || [1, 1, 1];
    gl.uniform3f(U('uInvGain'), e[0] / display.gain, e[1] / display.gain, e[2] / display.gain);
  } else {
    gl.uniform1i(U('uHdr'), 0);
    gl.uniform3f(U('uInvGain'), 1, 1, 1);
  }

  // ---- Images: embedded (file://) or fetched (served) ----------------------------------------
  const embedded = D.embedded || {};
  async function loadBitmap(name) {
    let blob;
    if (embedded[name]) {
      const bin = atob(embedded[name]);
      const bytes = new Uint8Array(bin.length);
      for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
      blob = new Blob([bytes], { type: name.endsWith('.png') ? 'image/png' : 'image/jpeg' });
    } else {
      if (location.protocol === 'file:') throw new Error(name + ' is not embedded: serve the folder (see docs/viewer.md)');
      const r = await fetch(name);
      if (!r.ok) throw new Error(name + ': HTTP ' + r.status);
      blob = await r.blob();
    }
    try {
      return await createImageBitmap(blob, { colorSpaceConversion: 'none', premultiplyAlpha: 'none' });
    } catch (e) {
      throw new Error(name + ': not an image the browser decodes (' + String(e.message || e) + ')');
    }
  }
  function textureFrom(bitmap, mipmap) {
    const t = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, bitmap);
    if (mipmap) gl.generateMipmap(gl.TEXTURE_2D);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, mipmap ? gl.LINEAR_MIPMAP_LINEAR : gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return t;
  }

  // ---- Levels and tiles ------------------------------------------------------------------------
  // Untiled: one level, one tile (plane_j.jpg). Deep zoom: level L is ceil(W / 2^(max - L)) wide,
  // tiles of tileSize with `overlap` pixels shared on inner edges.
  const dz = D.tiles;
  const maxLevel = dz ? Math.ceil(Math.log2(Math.max(W, H))) : 0;
  const levelSize = (L) => dz ? [Math.ceil(W / 2 ** (maxLevel - L)), Math.ceil(H / 2 ** (maxLevel - L))] : [W, H];
  const tiles = new Map();  // key -> {state, textures}
  const pendingAt = {};     // level -> tiles still loading
  let soon = null;
  // A full redraw costs a frame of the CPU rasteriser under SwiftShader: redraw when a level's
  // last pending tile arrives, otherwise at most every 300 ms while tiles stream in.
  function tileArrived(L) {
    if (--pendingAt[L] === 0) redraw();
    else if (!soon) soon = setTimeout(() => { soon = null; redraw(); }, 300);
  }
  function tileKey(L, x, y) { return L + '/' + x + '_' + y; }
  function requestTile(L, x, y) {
    const key = tileKey(L, x, y);
    let t = tiles.get(key);
    if (t) return t;
    t = { state: 'loading', textures: null };
    tiles.set(key, t);
    pendingAt[L] = (pendingAt[L] || 0) + 1;
    const names = [];
    for (let j = 0; j < nfiles; ++j)
      names.push(dz ? `plane_${j}_files/${L}/${x}_${y}.${dz.format}` : `plane_${j}.jpg`);
    Promise.all(names.map(loadBitmap)).then((bitmaps) => {
      t.textures = bitmaps.map((b) => textureFrom(b, !dz));
      t.w = bitmaps[0].width; t.h = bitmaps[0].height;
      bitmaps.forEach((b) => b.close());
      t.state = 'ready';
      tileArrived(L);
    }).catch((e) => { t.state = 'failed'; failView(String(e.message || e)); tileArrived(L); });
    return t;
  }

  // ---- View ----------------------------------------------------------------------------------
  const native = params.get('fit') === 'native';
  const view = { cx: W / 2, cy: H / 2, zoom: 1 };
  function resize() {
    if (native) {
      canvas.width = W; canvas.height = H;
      canvas.style.width = W + 'px'; canvas.style.height = H + 'px';
    } else {
      const dpr = window.devicePixelRatio || 1;
      canvas.width = Math.max(1, Math.round(canvas.clientWidth * dpr));
      canvas.height = Math.max(1, Math.round(canvas.clientHeight * dpr));
    }
  }
  function fitView() {
    view.cx = W / 2; view.cy = H / 2;
    view.zoom = native ? 1 : Math.min(canvas.width / W, canvas.height / H);
  }

  // Which tiles cover the view at which level; `need` = the tiles of the level the zoom calls for.
  function visibleTiles() {
    const cw = canvas.width, ch = canvas.height, z = view.zoom;
    const x0 = Math.max(0, view.cx - cw / 2 / z), x1 = Math.min(W, view.cx + cw / 2 / z);
    const y0 = Math.max(0, view.cy - ch / 2 / z), y1 = Math.min(H, view.cy + ch / 2 / z);
    if (!dz) return { levels: [{ L: 0, list: [[0, 0]] }] };
    // finest level needed: downsampling 2^k <= 1/zoom
    const k = Math.max(0, Math.floor(Math.log2(1 / z) + 1e-9));
    const need = Math.max(0, maxLevel - k);
    const out = [];
    for (let L = Math.max(0, need - 3); L <= need; ++L) {
      const f = 2 ** (maxLevel - L), T = dz.tileSize, [lw, lh] = levelSize(L);
      const list = [];
      for (let ty = Math.floor(y0 / f / T); ty <= Math.min(Math.floor((y1 / f - 1e-9) / T), Math.ceil(lh / T) - 1); ++ty)
        for (let tx = Math.floor(x0 / f / T); tx <= Math.min(Math.floor((x1 / f - 1e-9) / T), Math.ceil(lw / T) - 1); ++tx)
          list.push([tx, ty]);
      out.push({ L, list });
    }
    return { levels: out };
  }

  let mode = 'relight';
  let images = {};
  let frameReady = null;  // resolves when every needed tile is drawn
  function redraw() {
    if (!redraw.queued) { redraw.queued = true; requestAnimationFrame(draw); }
  }
  function draw() {
    redraw.queued = false;
    const cw = canvas.width, ch = canvas.height, z = view.zoom;
    gl.viewport(0, 0, cw, ch);
    gl.clearColor(0.125, 0.125, 0.125, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    const toClip = (ix, iy) => [((ix - view.cx) * z + cw / 2) / cw * 2 - 1, 1 - ((iy - view.cy) * z + ch / 2) / ch * 2];
    if (mode !== 'relight') {
      const img = images[mode];
      if (!img) return;
      gl.uniform1i(U('uMode'), 1);
      gl.activeTexture(gl.TEXTURE14);
      gl.bindTexture(gl.TEXTURE_2D, img);
      const a = toClip(0, 0), b = toClip(W, H);
      gl.uniform4f(U('uRect'), a[0], a[1], b[0], b[1]);
      gl.uniform4f(U('uTex'), 0, 0, 1, 1);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
      settle(true, true);
      return;
    }
    gl.uniform1i(U('uMode'), 0);
    const vis = visibleTiles();
    // The level below the needed one is requested first, the needed one once it is complete
    // (a whole picture soon, then the detail); levels further down are drawn if loaded.
    const need = vis.levels[vis.levels.length - 1].L;
    const complete = {};
    for (const { L, list } of vis.levels) {
      const wanted = L === need - 1 || (L === need && (need === 0 || complete[need - 1] !== false));
      complete[L] = true;
      const f = dz ? 2 ** (maxLevel - L) : 1, T = dz ? dz.tileSize : Math.max(W, H), ov = dz ? dz.overlap : 0;
      const [lw, lh] = levelSize(L);
      for (const [tx, ty] of list) {
        const t = wanted ? requestTile(L, tx, ty) : tiles.get(tileKey(L, tx, ty));
        if (!t || t.state !== 'ready') { if (!t || t.state === 'loading') complete[L] = false; continue; }
        // content rect in level pixels, and where it sits in the tile image
        const cx0 = tx * T, cy0 = ty * T, cx1 = Math.min(cx0 + T, lw), cy1 = Math.min(cy0 + T, lh);
        const ox = tx > 0 ? ov : 0, oy = ty > 0 ? ov : 0;
        for (let j = 0; j < nfiles; ++j) {
          gl.activeTexture(gl.TEXTURE0 + j);
          gl.bindTexture(gl.TEXTURE_2D, t.textures[j]);
        }
        const a = toClip(cx0 * f, cy0 * f), b = toClip(Math.min(cx1 * f, W), Math.min(cy1 * f, H));
        gl.uniform4f(U('uRect'), a[0], a[1], b[0], b[1]);
        const u0 = ox / t.w, v0 = oy / t.h;
        const u1 = (ox + (Math.min(cx1 * f, W) / f - cx0)) / t.w, v1 = (oy + (Math.min(cy1 * f, H) / f - cy0)) / t.h;
        gl.uniform4f(U('uTex'), u0, v0, u1, v1);
        gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
      }
    }
    settle(complete[need], complete[need] || complete[need - 1] === true);
  }
  // Waiters for a drawn frame: 'full' (every tile of the needed level) or 'any' (a whole
  // picture, the needed level or the one below it).
  let settleWaiters = [];
  function settle(full, any) {
    if (!any) return;
    gl.finish();
    const keep = [];
    for (const w of settleWaiters) {
      if (full || w.kind === 'any') w.resolve(); else keep.push(w);
    }
    settleWaiters = keep;
  }
  function whenDrawn(kind = 'full') { return new Promise((resolve) => { settleWaiters.push({ kind, resolve }); redraw(); }); }

  // ---- Lamps and controls ------------------------------------------------------------------------
  // ?light=x,y,z[,r,g,b[,i]] (repeat the parameter, or separate lamps with ';')
  function parseLamps(text) {
    return text.split(';').filter((s) => s.trim()).map((s) => {
      const v = s.split(',').map(Number);
      if (!(v.length === 3 || v.length === 6 || v.length === 7) || v.some((x) => !Number.isFinite(x)))
        fail('light "' + s + '": x,y,z or x,y,z,r,g,b or x,y,z,r,g,b,i expected');
      return { dir: unit(v.slice(0, 3)), color: v.length >= 6 ? v.slice(3, 6) : [1, 1, 1], intensity: v.length === 7 ? v[6] : 1 };
    });
  }
  let lamps = params.getAll('light').flatMap(parseLamps);
  if (!lamps.length) lamps = [{ dir: unit(D.default_light || [0, 0, 1]), color: [1, 1, 1], intensity: 1 }];
  let selected = 0;
  let exposureEv = Number(params.get('exposure') || 0);
  if (!Number.isFinite(exposureEv)) fail('exposure: a number of stops expected');

  const lampsDiv = document.getElementById('lamps');
  const hex = (c) => '#' + c.map((v) => Math.round(Math.min(1, Math.max(0, v)) * 255).toString(16).padStart(2, '0')).join('');
  function renderLampList() {
    lampsDiv.innerHTML = '';
    lamps.forEach((lamp, i) => {
      const row = document.createElement('div');
      row.className = 'lamp';
      row.innerHTML = `<input type="radio" name="sel" ${i === selected ? 'checked' : ''} title="move this lamp">
        <input type="color" value="${hex(lamp.color)}" title="colour">
        <input type="range" min="0" max="4" step="0.05" value="${lamp.intensity}" title="intensity">
        <button title="remove" ${lamps.length === 1 ? 'disabled' : ''}>&minus;</button>
        <span class="dir">(${lamp.dir.map((v) => v.toFixed(3)).join(', ')}) &times;${lamp.intensity.toFixed(2)}</span>`;
      const [radio, color, intensity, remove] = row.querySelectorAll('input, button');
      radio.onchange = () => { selected = i; };
      color.oninput = () => {
        const h = color.value;
        lamp.color = [1, 3, 5].map((k) => parseInt(h.substr(k, 2), 16) / 255);
        changed(false);
      };
      intensity.oninput = () => { lamp.intensity = Number(intensity.value); changed(false); row.querySelector('.dir').innerHTML = `(${lamp.dir.map((v) => v.toFixed(3)).join(', ')}) &times;${lamp.intensity.toFixed(2)}`; };
      remove.onclick = () => { lamps.splice(i, 1); selected = Math.min(selected, lamps.length - 1); changed(true); };
      lampsDiv.appendChild(row);
    });
  }
  function changed(list) {
    uploadLamps();
    if (list) renderLampList();
    redraw();
  }
  document.getElementById('add-lamp').onclick = () => {
    if (lamps.length >= MAX_LAMPS) return;
    lamps.push({ dir: unit([-0.4, 0.4, 0.8]), color: [1, 1, 1], intensity: 1 });
    selected = lamps.length - 1;
    changed(true);
  };
  const exposure = document.getElementById('exposure'), exposureValue = document.getElementById('exposure-value');
  function applyExposure() {
    gl.uniform1f(U('uExposure'), 2 ** exposureEv);
    exposureValue.textContent = (exposureEv > 0 ? '+' : '') + exposureEv.toFixed(1) + ' EV';
  }
  exposure.value = exposureEv;
  exposure.oninput = () => { exposureEv = Number(exposure.value); applyExposure(); redraw(); };
  const modeSelect = document.getElementById('mode');
  modeSelect.onchange = () => { mode = modeSelect.value; redraw(); };

  // pointer: drag moves the selected lamp (disc of the canvas = the hemisphere), shift/right pans
  let drag = null;
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => {
    canvas.setPointerCapture(e.pointerId);
    drag = { pan: e.shiftKey || e.button === 2, x: e.clientX, y: e.clientY };
    if (!drag.pan) moveLamp(e);
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    if (drag.pan) {
      const dpr = native ? 1 : (window.devicePixelRatio || 1);
      view.cx -= (e.clientX - drag.x) * dpr / view.zoom;
      view.cy -= (e.clientY - drag.y) * dpr / view.zoom;
      drag.x = e.clientX; drag.y = e.clientY;
      redraw();
    } else moveLamp(e);
  });
  canvas.addEventListener('pointerup', () => { drag = null; renderLampList(); });
  function moveLamp(e) {
    const r = canvas.getBoundingClientRect();
    const radius = Math.min(r.width, r.height) / 2;  // the inscribed disc is the hemisphere
    let x = (e.clientX - r.left - r.width / 2) / radius, y = (r.top + r.height / 2 - e.clientY) / radius;
    const n = Math.hypot(x, y);
    if (n > 0.999) { x *= 0.999 / n; y *= 0.999 / n; }
    lamps[selected].dir = [x, y, Math.sqrt(Math.max(0, 1 - x * x - y * y))];
    changed(false);
  }
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    const r = canvas.getBoundingClientRect(), dpr = canvas.width / r.width;
    const px = (e.clientX - r.left) * dpr, py = (e.clientY - r.top) * dpr;
    const ix = view.cx + (px - canvas.width / 2) / view.zoom, iy = view.cy + (py - canvas.height / 2) / view.zoom;
    const f = Math.exp(-e.deltaY * 0.0015);
    view.zoom = Math.min(32, Math.max(0.01, view.zoom * f));
    view.cx = ix - (px - canvas.width / 2) / view.zoom;
    view.cy = iy - (py - canvas.height / 2) / view.zoom;
    redraw();
  }, { passive: false });
  canvas.addEventListener('dblclick', () => { fitView(); redraw(); });
  window.addEventListener('resize', () => { resize(); redraw(); });

  // ---- Start -----------------------------------------------------------------------------------
  document.getElementById('model').textContent =
    `${W}x${H}, ${type} ${colorspace}, ${nplanes} planes${dz ? ', deep zoom' : ''}` + (D.source ? ' — ' + D.source : '');
  resize();
  fitView();
  if (params.has('zoom')) view.zoom = Number(params.get('zoom'));
  uploadLamps();
  renderLampList();
  applyExposure();
  for (const name of ['normals', 'albedo']) {
    if (!D[name]) continue;
    loadBitmap(D[name]).then((b) => {
      images[name] = textureFrom(b, true);
      b.close();
      modeSelect.querySelector(`option[value=${name}]`).disabled = false;
      redraw();
    }).catch((e) => { message.textContent = String(e.message || e); });  // the relit view stands
  }
  if (params.get('view')) { mode = params.get('view'); modeSelect.value = mode; }
  const status = document.getElementById('status');
  whenDrawn('any').then(() => viewEnds[0].resolve(performance.now()));
  whenDrawn('full').then(() => viewEnds[1].resolve(performance.now()));
  if (params.get('timing') === '1') {
    Promise.all([window.rigFirstView, window.rigFullView]).then(([a, b]) => {
      status.textContent = `first view ${a.toFixed(0)} ms, every tile of its level ${b.toFixed(0)} ms`;
    });
  }
})();
