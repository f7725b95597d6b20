// Fuzzes what `rig resume` does with a journal's records (journal_adapter.h ResumeUpToDevices:
// Session::OpenExisting, then the capture daemon's ReadJournal / VerifyIndex / CheckPlan):
// the input is journal.jsonl of a small session (2 poses × 2 exposures) whose frames folder
// holds the four files the seeds' records name (bytes "fuzz frame <pose> <i>").
//
// Machine safety: the guarded reader refuses a record whose "file" leaves the session (an
// absolute path, ".."), and the tests of tests/capture hold it to that. Should it ever fail,
// resume would move what it finds there aside, so inputs naming such a file are still skipped
// here: fuzzing never touches anything outside the scratch folder.
#include <cstdint>

#include <nlohmann/json.hpp>

#include "config/config.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/journal_adapter.h"

namespace {

namespace fs = std::filesystem;

constexpr const char* kConfig = R"([grid]
h_min_deg = 0
h_max_deg = 10
h_step_deg = 10
v_min_deg = 0
v_max_deg = 0
v_step_deg = 10
[bracket]
center_s = 0.01
ev_step = 1.0
count = 2
[camera]
backend = "sim"
retries = 0
[motor]
backend = "sim"
retries = 0
[lamp]
backend = "sim"
[sim]
width = 16
height = 12
)";

std::string g_session_toml;

// Does any record name a file outside the session folder?
bool NamesOutside(std::string_view text) {
  size_t pos = 0;
  while (pos < text.size()) {
    size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    auto j = nlohmann::json::parse(text.substr(pos, nl - pos), nullptr, false);
    if (j.is_object() && j.contains("file") && j["file"].is_string()) {
      const std::string f = j["file"].get<std::string>();
      if (f.empty() || fs::path(f).is_absolute() || f.find("..") != std::string::npos ||
          f.find('\0') != std::string::npos)
        return true;
    }
    pos = nl + 1;
  }
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  rig::ConfigResult c = rig::ParseConfig(kConfig, "fuzz session.toml");
  if (!c.ok()) {
    std::fprintf(stderr, "%s\n", c.AsError().ToString().c_str());
    std::abort();
  }
  g_session_toml = rig::ToToml(c.config);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view journal = rig::fuzz::AsText(data, size);
  if (NamesOutside(journal)) return -1;  // not added to the corpus
  const fs::path dir = rig::fuzz::Scratch() / "session";
  std::error_code ec;
  fs::remove_all(dir, ec);
  for (const char* pose : {"h000_v00", "h010_v00"}) {
    fs::create_directories(dir / "frames" / pose);
    rig::fuzz::WriteFile(dir / "frames" / pose / "0_0.00707.jpg",
                         std::string("fuzz frame ") + pose + " 0");
    rig::fuzz::WriteFile(dir / "frames" / pose / "1_0.01414.jpg",
                         std::string("fuzz frame ") + pose + " 1");
  }
  rig::fuzz::WriteFile(dir / "session.toml", g_session_toml);
  rig::fuzz::WriteFile(dir / "journal.jsonl", journal);
  rig::Status st = rig::fuzz::ResumeUpToDevices(dir);
  // The one way it may end: a refusal of bad input, or the camera's "captures nothing" fault.
  if (!st.ok() && st.error().code != rig::ErrorCode::kFault &&
      st.error().code != rig::ErrorCode::kUnsupported)
    rig::fuzz::CheckRefusal(st.error());
  return 0;
}
