// SIGINT/SIGTERM as a flag: a command finishes the frame in hand, parks safely and exits
// 128 + signal. Long waits poll StopRequested() (or sleep through SleepUnlessStopped()).
#pragma once

#include "config/config.h"

namespace rig {

// Installs the handlers (idempotent). The first signal sets the flag; a second one of the
// same kind restores the default action, so a stuck process can still be killed.
void InstallStopHandlers();
// 0 when no stop was requested, else the signal number.
int StopSignal();
inline bool StopRequested() { return StopSignal() != 0; }
// For tests and for a stop requested by the program itself.
void RequestStop(int signal_number);
void ClearStopForTesting();
// The first SIGINT/SIGTERM the handlers caught (0: none). RequestStop() does not set it: a
// long-running service tells a stop it asked for itself from a signal sent to the process.
int CaughtSignal();
// Clears a stop the program requested (RequestStop), never one a caught signal set.
void ClearRequestedStop();

// Sleeps `d`, waking early (returning false) if a stop is requested.
bool SleepUnlessStopped(Seconds d);

}  // namespace rig
