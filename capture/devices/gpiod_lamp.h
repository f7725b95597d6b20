// The lamp's relay on a GPIO line through libgpiod (Debian 12's 1.6 API).
//
// The line is requested as an output, driven inactive (lamp off) at once; active-low relays
// are handled by libgpiod's ACTIVE_LOW flag, so "on" is always logical 1. Close() — on exit,
// on a fault, on Ctrl-C — drives it off before releasing it. If the process dies without
// Close() (SIGKILL, a crash), the kernel releases the line and it keeps its last value: a
// lamp that was on stays on until the next `rig capture`/`rig resume` opens the line (which
// drives it off first). Wire the relay's default (unpowered) contact to "lamp off".
#pragma once

#include <memory>

#include "config/config.h"
#include "capture/devices/lamp.h"

namespace rig {

std::unique_ptr<Lamp> MakeGpiodLamp(const LampConfig& config);

}  // namespace rig
