// Fuzzes the session journal's guarded reader (capture/session/journal_reader.h ParseJournal on
// the bytes, then journal.jsonl as a file: Journal::Read, and Journal::Open's cut of a torn
// tail, through journal_adapter.h). What resume then does with the records is fuzzed by
// journal_resume_fuzz.cc.
#include <cstdint>

#include "capture/session/journal_reader.h"
#include "tests/fuzz/fuzz_support.h"
#include "tests/fuzz/journal_adapter.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto parsed = rig::ParseJournal(rig::fuzz::AsText(data, size), "fuzz journal.jsonl");
  if (!parsed.ok()) rig::fuzz::CheckRefusal(parsed.error());
  if (parsed.ok() && parsed->valid_bytes > size) __builtin_trap();
  const auto path = rig::fuzz::Scratch() / "journal.jsonl";
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data, size));
  rig::Status st = rig::fuzz::ReadJournalFile(path);
  if (!st.ok()) rig::fuzz::CheckRefusal(st.error());
  return 0;
}
