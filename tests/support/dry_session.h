// Test support: one dry-run session captured for a whole test suite (`rig capture --dry-run`
// of config/sim.toml with `extra` TOML merged over it), removed with the suite's folder.
//
//   class RenderCommand : public testing::DrySessionSuite<RenderCommand> {
//     static void SetUpTestSuite() { Capture("render", "[sim]\nwidth = 96\n"); }
//   };
//   ... *session_ (the session folder), *dir_ (the suite's temporary folder)
#pragma once

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "tests/support/run_rig.h"

namespace rig::testing {

template <class Suite>
class DrySessionSuite : public ::testing::Test {
 protected:
  static void Capture(const std::string& name, const std::string& extra) {
    dir_ = new std::string(FreshTempDir(name));
    const std::string cfg = WriteSimConfig(*dir_, extra);
    session_ = new std::string(*dir_ + "/S");
    auto r = RunRig("capture --config " + cfg + " --out " + *session_ + " --dry-run --no-progress");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  static void TearDownTestSuite() {
    if (dir_ != nullptr) std::filesystem::remove_all(*dir_);
    delete dir_;
    delete session_;
    dir_ = session_ = nullptr;
  }
  static inline std::string* dir_ = nullptr;
  static inline std::string* session_ = nullptr;
};

}  // namespace rig::testing
