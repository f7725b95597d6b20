// Per-frame overhead of the gphoto2 path on libgphoto2's virtual camera: set the exposure,
// read it back, capture, download to memory, drain events (and delete, with --delete).
// Run it through the virtual camera's environment:
//
//   scripts/with-vusb-camera.sh build/bench/gphoto2_bench [--frames 30] [--delete]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "capture/devices/gphoto2_camera.h"
#include "config/log.h"

int main(int argc, char** argv) {
  int frames = 30;
  bool del = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--frames" && i + 1 < argc) frames = std::atoi(argv[++i]);
    if (a == "--delete") del = true;
  }
  const char* port = std::getenv("RIG_VUSB_PORT");
  const char* model = std::getenv("RIG_VUSB_MODEL");
  if (!port || !model) {
    std::fprintf(stderr, "run through scripts/with-vusb-camera.sh\n");
    return 2;
  }
  rig::SetLogLevel("warn");
  rig::CameraConfig c;
  c.backend = "gphoto2";
  c.port = port;
  c.model = model;
  c.delete_from_card = del;
  auto cam = rig::MakeGPhoto2Camera(c);
  const auto t_open = std::chrono::steady_clock::now();
  if (rig::Status st = cam->Open(); !st.ok()) {
    std::fprintf(stderr, "%s\n", st.error().ToString().c_str());
    return 1;
  }
  const double open_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_open).count();
  auto speeds = cam->ShutterSpeeds();
  if (!speeds.ok()) return 1;
  std::vector<double> t;
  size_t bytes = 0;
  for (int i = 0; i < frames; ++i) {
    const rig::Seconds s = (*speeds)[i % speeds->size()];
    const auto a = std::chrono::steady_clock::now();
    auto f = cam->Capture(s);
    if (!f.ok()) {
      std::fprintf(stderr, "%s\n", f.error().ToString().c_str());
      return 1;
    }
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count());
    bytes = f->files[0].bytes.size();
  }
  std::sort(t.begin(), t.end());
  std::printf("gphoto2 on the virtual camera (%s), %d frames of %zu bytes, exposure changed every frame%s\n",
              model, frames, bytes, del ? ", deleted after download" : "");
  std::printf("  open                 %8.1f ms\n", open_s * 1e3);
  std::printf("  per frame: median   %8.1f ms, min %.1f, max %.1f (set + read back + capture + download + events)\n",
              t[t.size() / 2] * 1e3, t.front() * 1e3, t.back() * 1e3);
  return 0;
}
