// The stop flag: a stop the program requested (the daemon's POST /api/stop) can be cleared
// for the next job; one a caught SIGINT/SIGTERM set cannot.
#include "capture/devices/signals.h"

#include <signal.h>

#include <gtest/gtest.h>

namespace rig {
namespace {

TEST(StopSignals, RequestedStopClearsButACaughtSignalStays) {
  ClearStopForTesting();
  RequestStop(SIGTERM);
  EXPECT_TRUE(StopRequested());
  EXPECT_EQ(CaughtSignal(), 0);
  ClearRequestedStop();
  EXPECT_FALSE(StopRequested());

  InstallStopHandlers();
  ASSERT_EQ(raise(SIGINT), 0);
  EXPECT_EQ(CaughtSignal(), SIGINT);
  EXPECT_EQ(StopSignal(), SIGINT);
  ClearRequestedStop();
  EXPECT_EQ(StopSignal(), SIGINT);  // the signal's stop is not the program's to clear

  // A signal after a requested stop is still seen as the first signal caught.
  ClearStopForTesting();
  RequestStop(SIGTERM);
  ASSERT_EQ(raise(SIGINT), 0);
  EXPECT_EQ(CaughtSignal(), SIGINT);
  ClearRequestedStop();
  EXPECT_TRUE(StopRequested());
  ClearStopForTesting();
}

}  // namespace
}  // namespace rig
