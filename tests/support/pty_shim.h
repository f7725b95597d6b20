// Test-only: the libserialport pseudo-terminal interposer (tests/support/pty_shim.cc).
#pragma once

namespace rig::testing {

// Referencing this from a test pulls the interposer (ioctl, readlink, __lxstat) into the
// test binary, so the real libserialport can open the emulators' pseudo-terminals.
bool PtyShimLinked();
// How many calls the interposer answered itself (for checking it is active).
int PtyShimCalls();

}  // namespace rig::testing
