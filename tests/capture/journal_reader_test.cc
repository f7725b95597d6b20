// The journal's guarded reader: every record validated field by field, paths confined to
// the session, errors as journal.jsonl:LINE.
#include "capture/session/journal_reader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace rig {
namespace {

using ::testing::HasSubstr;

const char* kFrame =
    R"({"event":"frame","pose":"h000_v00","index":0,"exposure_s":0.01,"file":"frames/h000_v00/0_0.01000.jpg","bytes":10,"crc32":123})";

std::string Journal(const std::string& bad_line) {
  return std::string(R"({"event":"start","pid":1})") + "\n" + kFrame + "\n" + bad_line + "\n" +
         R"({"event":"pose_done","pose":"h000_v00"})" + "\n";
}

TEST(JournalReader, ValidRecordsAndUnknownEventsAreKept) {
  auto j = ParseJournal(Journal(R"({"event":"homed"})") + R"({"event":"some_future_event","x":[1]})" + "\n",
                        "S/journal.jsonl");
  ASSERT_TRUE(j.ok()) << j.error().ToString();
  EXPECT_EQ(j->records.size(), 5u);
  EXPECT_FALSE(j->torn_tail);
}

TEST(JournalReader, WrongTypesAndMissingKeysNameTheLine) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"event":"frame","pose":5,"index":0,"exposure_s":0.01,"file":"frames/a/b.jpg","bytes":1,"crc32":1})", "'pose'"},
      {R"({"event":"frame","pose":"h000_v00","index":0,"exposure_s":0.01,"file":"frames/a/b.jpg","bytes":1})", "'crc32' is missing"},
      {R"({"event":7})", "'event' must be a string"},
      {R"({"event":"plan","poses":3,"exposures_s":[0.1]})", "'poses'"},
      {R"({"event":"plan","poses":["h000_v00"],"exposures_s":[]})", "'exposures_s'"},
      {R"({"event":"frame","pose":"h000_v00","index":-1,"exposure_s":0.01,"file":"frames/a/b.jpg","bytes":1,"crc32":1})", "'index'"},
      {R"({"event":"frame","pose":"h000_v00","index":0,"exposure_s":0.01,"file":"frames/a/b.jpg","bytes":1,"crc32":4294967296})", "'crc32'"},
      {R"({"event":"frame","pose":"h000_v00","index":0,"exposure_s":-1,"file":"frames/a/b.jpg","bytes":1,"crc32":1})", "'exposure_s'"},
      {R"({"event":"frame","pose":"../../etc","index":0,"exposure_s":0.01,"file":"frames/a/b.jpg","bytes":1,"crc32":1})", "'pose'"},
      {R"([1,2,3])", "JSON object"},
      {R"({"pose":"h000_v00"})", "no 'event'"},
      {R"({"event":"config","digest":"x","settings":{"a":1}})", "'settings'"},
      {R"({"event":"frame","pose":"h000_v00","index":1.5,"exposure_s":0.01,"file":"frames/a/b.jpg","bytes":1,"crc32":1})", "'index'"},
  };
  for (const auto& [line, what] : cases) {
    auto j = ParseJournal(Journal(line), "S/journal.jsonl");
    ASSERT_FALSE(j.ok()) << line;
    EXPECT_EQ(j.error().context, "S/journal.jsonl:3") << line;
    EXPECT_THAT(j.error().message, HasSubstr(what)) << line;
    EXPECT_EQ(j.error().ExitCode(), 2);
  }
}

TEST(JournalReader, FilePathsAreConfinedToTheSessionFrames) {
  for (const char* file : {"/etc/passwd", "../../x.jpg", "frames/../../x.jpg", "frames/a/./b.jpg",
                                 "frames//b.jpg", "hdr/h000_v00.exr", "frames\\\\a.jpg", ""}) {
    const std::string line =
        R"({"event":"frame","pose":"h000_v00","index":0,"exposure_s":0.01,"file":")" + std::string(file) +
        R"(","bytes":1,"crc32":1})";
    auto j = ParseJournal(Journal(line), "S/journal.jsonl");
    ASSERT_FALSE(j.ok()) << file;
    EXPECT_THAT(j.error().message, HasSubstr("'file'")) << file;
  }
  EXPECT_EQ(SessionRelativePathProblem("frames/h000_v00/0_0.01000.jpg"), "");
  EXPECT_NE(SessionRelativePathProblem("/abs"), "");
  EXPECT_NE(SessionRelativePathProblem("a/../b"), "");
}

TEST(JournalReader, TornTailIsAWarningAndDamageInTheMiddleAnError) {
  auto torn = ParseJournal(std::string(kFrame) + "\n{\"event\":\"fra", "J");
  ASSERT_TRUE(torn.ok());
  EXPECT_TRUE(torn->torn_tail);
  EXPECT_EQ(torn->records.size(), 1u);
  EXPECT_EQ(torn->valid_bytes, std::string(kFrame).size() + 1);
  auto mid = ParseJournal(std::string(kFrame) + "\n{not json\n" + kFrame + "\n", "J");
  ASSERT_FALSE(mid.ok());
  EXPECT_EQ(mid.error().context, "J:2");
}

TEST(JournalReader, ArbitraryBytesNeverThrow) {
  // A few hostile shapes: deep nesting, huge numbers, NUL bytes, invalid UTF-8.
  const std::vector<std::string> inputs = {
      std::string(100000, '[') + "\n", "{\"event\":\"frame\",\"index\":1e400}\n",
      std::string("{\"event\":\"a\0b\"}\n", 15), "{\"event\":\"\xff\xfe\"}\n",
      "{\"event\":\"plan\",\"poses\":[\"h1e999_v0\"],\"exposures_s\":[1]}\n"};
  for (const auto& in : inputs) {
    EXPECT_NO_THROW({ auto r = ParseJournal(in, "J"); (void)r; });
  }
}

}  // namespace
}  // namespace rig
