// Test-only interposer that lets the real libserialport 0.1.1 open pseudo-terminals.
//
// libserialport refuses a pty in exactly two places (see docs/motion.md):
//  - sp_get_port_by_name() -> get_port_details() lstat()s and readlink()s
//    /sys/class/tty/<name>; a pty (/dev/pts/N) has no such sysfs entry ("Device not found").
//  - sp_open() -> get_config() asks the modem lines with ioctl(TIOCMGET), which a pty
//    answers with ENOTTY.
// This object defines __lxstat (the glibc entry point the Debian build of libserialport
// 0.1.1 imports for lstat), readlink and ioctl. For /sys/class/tty/pts/N it reports a
// symlink to a "virtual" tty; for TIOCMGET/TIOCMSET/TIOCMBIS/TIOCMBIC on a pty slave it
// keeps the modem bits in a table. Everything else is forwarded to the next definition
// (libc) through dlsym(RTLD_NEXT). It is linked into the test binaries (rig_test_support)
// and built as librig_pty_shim.so (target rig_pty_shim, installed to lib/rig/) for
// LD_PRELOAD in front of the installed rig; never linked into rig itself.
#undef _FORTIFY_SOURCE
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <errno.h>
#include <stdarg.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/types.h>

#include <atomic>

#include "tests/support/pty_shim.h"

namespace {

constexpr char kPtsSysfs[] = "/sys/class/tty/pts/";
constexpr char kPtsSysfsTarget[] = "../../devices/virtual/tty/pts";

bool IsPtsSysfsPath(const char* path) {
  return path != nullptr && strncmp(path, kPtsSysfs, sizeof(kPtsSysfs) - 1) == 0;
}

// Unix98 pty slaves have majors 136..143 (Documentation/admin-guide/devices.txt).
bool IsPtySlave(int fd) {
  struct stat st;
  if (fstat(fd, &st) != 0 || !S_ISCHR(st.st_mode)) return false;
  unsigned maj = major(st.st_rdev);
  return maj >= 136 && maj <= 143;
}

// Modem-line bits per file descriptor (a pty has none; we remember what was set).
constexpr int kMaxFd = 4096;
std::atomic<int> g_modem_bits[kMaxFd];
std::atomic<int> g_calls{0};

using IoctlFn = int (*)(int, unsigned long, ...);
using ReadlinkFn = ssize_t (*)(const char*, char*, size_t);

IoctlFn RealIoctl() {
  static IoctlFn fn = reinterpret_cast<IoctlFn>(dlsym(RTLD_NEXT, "ioctl"));
  return fn;
}
ReadlinkFn RealReadlink() {
  static ReadlinkFn fn = reinterpret_cast<ReadlinkFn>(dlsym(RTLD_NEXT, "readlink"));
  return fn;
}

}  // namespace

extern "C" {

// glibc < 2.33 headers turned lstat() into __lxstat(_STAT_VER, ...); the library still
// imports it. On x86-64 the _STAT_VER_KERNEL layout is struct stat, so lstat() forwards.
int __lxstat(int ver, const char* path, struct stat* st);
int __lxstat(int ver, const char* path, struct stat* st) {
  (void)ver;
  if (IsPtsSysfsPath(path)) {
    g_calls.fetch_add(1);
    memset(st, 0, sizeof(*st));
    st->st_mode = S_IFLNK | 0777;
    return 0;
  }
  return lstat(path, st);
}

ssize_t readlink(const char* path, char* buf, size_t size) {
  if (IsPtsSysfsPath(path)) {
    g_calls.fetch_add(1);
    size_t n = sizeof(kPtsSysfsTarget) - 1;
    if (n > size) n = size;
    memcpy(buf, kPtsSysfsTarget, n);
    return static_cast<ssize_t>(n);
  }
  ReadlinkFn real = RealReadlink();
  if (real == nullptr) {
    errno = ENOSYS;
    return -1;
  }
  return real(path, buf, size);
}

int ioctl(int fd, unsigned long request, ...) {
  va_list ap;
  va_start(ap, request);
  void* arg = va_arg(ap, void*);
  va_end(ap);
  IoctlFn real = RealIoctl();
  if (real == nullptr) {
    errno = ENOSYS;
    return -1;
  }
  bool modem = request == TIOCMGET || request == TIOCMSET || request == TIOCMBIS ||
               request == TIOCMBIC;
  if (!modem || fd < 0 || fd >= kMaxFd) return real(fd, request, arg);
  int rc = real(fd, request, arg);
  if (rc == 0 || (errno != ENOTTY && errno != EINVAL) || !IsPtySlave(fd)) return rc;
  g_calls.fetch_add(1);
  int* bits = static_cast<int*>(arg);
  if (bits == nullptr) {
    errno = EFAULT;
    return -1;
  }
  // A freshly opened port: DTR and RTS up, and the "other side" present (CTS, DSR, CD).
  int current = g_modem_bits[fd].load();
  if (current == 0) current = TIOCM_DTR | TIOCM_RTS | TIOCM_CTS | TIOCM_DSR | TIOCM_CD;
  switch (request) {
    case TIOCMGET: *bits = current; break;
    case TIOCMSET: current = *bits | TIOCM_CTS | TIOCM_DSR | TIOCM_CD; break;
    case TIOCMBIS: current |= *bits; break;
    case TIOCMBIC: current &= ~*bits; break;
  }
  g_modem_bits[fd].store(current);
  return 0;
}

}  // extern "C"

namespace rig::testing {

bool PtyShimLinked() { return true; }
int PtyShimCalls() { return g_calls.load(); }

}  // namespace rig::testing
