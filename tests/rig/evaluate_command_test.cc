// `rig evaluate` end to end on tiny simulated sessions: every method and order has a row with
// finite numbers, the Pareto fronts are non-dominated, one model is marked as the choice, the
// charts are real PNGs, and a session folder can be evaluated again without simulation.
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/evaluate/evaluate.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

std::vector<std::map<std::string, std::string>> ReadCsv(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string h; std::getline(hs, h, ',');) header.push_back(h);
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::map<std::string, std::string> row;
    std::stringstream ls(line);
    std::string cell;
    for (size_t i = 0; i < header.size() && std::getline(ls, cell, ','); ++i) {
      if (!cell.empty() && cell[0] == '"') {  // quoted: the rest of the line
        std::string rest;
        std::getline(ls, rest);
        cell += rest.empty() ? "" : "," + rest;
      }
      row[header[i]] = cell;
    }
    rows.push_back(row);
  }
  return rows;
}

double Num(const std::map<std::string, std::string>& row, const std::string& key) {
  auto it = row.find(key);
  return it == row.end() || it->second.empty() ? std::nan("") : std::stod(it->second);
}

TEST(EvaluateCommand, DryRunWritesEveryMethodAndOrderTheFrontsTheChoiceAndCharts) {
  const std::string dir = testing::FreshTempDir("evaluate");
  const std::string out = dir + "/report";
  auto r = RunRig("evaluate --dry-run --quick --width 64 --height 48 --config " + testing::SourceDir() +
                  "/config/sim.toml --hdr-images " + testing::SharedDir() + "/data/hdr --out " + out);
  ASSERT_EQ(r.status, 0) << r.output;
  auto rows = ReadCsv(fs::path(out) / "methods.csv");
  // SH by quadrature, LS and RLS, HSH by LS and RLS at orders 0..6; PTM by LS and RLS at 1..4;
  // PCA with two value curves, 3..30 components (and the size the session's choice took, when
  // not among them), two JPEG qualities.
  size_t harmonic = 0, pca = 0;
  for (const auto& row : rows) (row.at("basis") == "pca" ? pca : harmonic) += 1;
  ASSERT_EQ(harmonic, 3u * 7 + 2u * 7 + 2u * 4);
  EXPECT_TRUE(pca == 2u * 5 * 2 || pca == 2u * 6 * 2) << pca;
  int selected = 0, supported = 0, refused = 0, session_default = 0;
  for (const auto& row : rows) {
    selected += row.at("selected") == "1";
    session_default += row.at("session_default") == "1";
    if (row.at("basis") == "pca") {
      // As stored: every plane's bytes (a 3-component model's are fewer than a 30's), no LOO.
      EXPECT_EQ(row.at("supported"), "1") << row.at("method") << row.at("order");
      EXPECT_GT(Num(row, "bytes_per_pixel"), 0);
      EXPECT_TRUE(std::isnan(Num(row, "loo_relative_rmse")));
      EXPECT_TRUE(std::isfinite(Num(row, "truth_relative_rmse"))) << row.at("method") << row.at("order");
      EXPECT_EQ(row.at("selected"), "0");
    }
    if (row.at("supported") != "1") {
      ++refused;
      EXPECT_FALSE(row.at("refusal").empty()) << row.at("basis") << row.at("method") << row.at("order");
      continue;
    }
    ++supported;
    for (const char* k : {"fit_time_s", "render_s_per_mp", "bytes_per_pixel", "truth_relative_rmse"}) {
      EXPECT_TRUE(std::isfinite(Num(row, k))) << k << " " << row.at("basis") << "-" << row.at("method") << " " << row.at("order");
    }
  }
  EXPECT_EQ(selected, 1);
  // The session's default model (its family chosen per byte) is one row, and the report names it.
  EXPECT_EQ(session_default, 1);
  {
    std::map<std::string, double> bytes;  // power1.25-q95 by components
    for (const auto& row : rows)
      if (row.at("basis") == "pca" && row.at("method") == "power1.25-q95") bytes[row.at("order")] = Num(row, "bytes_per_pixel");
    EXPECT_LT(bytes["3"], bytes["30"]);
  }
  // Least squares cannot fit SH order 4 and above on the 4-level grid: refused, not garbage.
  EXPECT_GE(refused, 3);
  EXPECT_GT(supported, 30);
  // The fronts: no supported row is at least as good on both axes and better on one.
  for (const char* axis : {"fit_time_s", "bytes_per_pixel"}) {
    const std::string flag = std::string(axis) == "fit_time_s" ? "pareto_time" : "pareto_storage";
    int on_front = 0;
    for (const auto& a : rows) {
      if (a.at("supported") != "1") continue;
      bool dominated = false;
      for (const auto& b : rows) {
        if (&a == &b || b.at("supported") != "1") continue;
        const double ca = Num(a, axis), cb = Num(b, axis);
        const double ea = Num(a, "truth_relative_rmse"), eb = Num(b, "truth_relative_rmse");
        if (cb <= ca && eb <= ea && (cb < ca || eb < ea)) dominated = true;
      }
      EXPECT_EQ(a.at(flag) == "1", !dominated) << axis << " " << a.at("basis") << "-" << a.at("method") << a.at("order");
      on_front += !dominated;
    }
    EXPECT_GE(on_front, 2) << axis;
  }
  for (const char* png : {"error_vs_time.png", "error_vs_storage.png", "condition_vs_order.png",
                          "extrapolation.png", "hdr_time_vs_error.png", "hdr_error_vs_exposures.png",
                          "hdr_error_vs_noise.png"}) {
    cv::Mat img = cv::imread((fs::path(out) / png).string());
    EXPECT_FALSE(img.empty()) << png;
    // Not a blank canvas.
    if (!img.empty()) {
      const cv::Mat white(img.size(), img.type(), cv::Scalar::all(255));
      EXPECT_GT(cv::norm(img, white, cv::NORM_L1), 1e5) << png;
    }
  }
  auto hdr = ReadCsv(fs::path(out) / "hdr_methods.csv");
  int ours = 0, debevec = 0, robertson = 0;
  for (const auto& row : hdr) {
    ours += row.at("method") == "ours";
    debevec += row.at("method") == "opencv-debevec";
    robertson += row.at("method") == "opencv-robertson";
  }
  EXPECT_GE(ours, 4);
  EXPECT_EQ(ours, debevec);
  EXPECT_EQ(ours, robertson);
  std::ifstream report(fs::path(out) / "report.md");
  std::stringstream text;
  text << report.rdbuf();
  EXPECT_THAT(text.str(), HasSubstr("## Findings"));
  EXPECT_THAT(text.str(), HasSubstr("No more model than the scene needs"));
  EXPECT_THAT(text.str(), HasSubstr("| matte |"));
  EXPECT_THAT(text.str(), HasSubstr("The session's default model is "));
  EXPECT_THAT(text.str(), HasSubstr("**session default**"));
  // The family choice under both held-out rules, the session's first, each beside the truth.
  const std::string rules = text.str();
  const size_t inside = rules.find("| matte | spread inside the lamps' outline (rig process) | 7 |");
  const size_t every = rules.find("| matte | every 6th | 7 |");
  EXPECT_NE(inside, std::string::npos) << rules;
  EXPECT_NE(every, std::string::npos);
  EXPECT_LT(inside, every);
  // Times are medians of runs (the default three), and the tables and report say so.
  EXPECT_THAT(text.str(), HasSubstr("wall seconds, the median of 3 runs of each"));
  EXPECT_THAT(text.str(), HasSubstr("| fit s (median of 3) |"));

  // The simulated session can be evaluated again as a session; a second report is refused.
  r = RunRig("evaluate " + out + "/sessions/matte --timing-runs 1 --hdr-images " + dir +
             "/none --out " + dir + "/again");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/again/methods.csv"));
  {
    std::ifstream again(dir + "/again/report.md");
    std::stringstream t;
    t << again.rdbuf();
    EXPECT_THAT(t.str(), HasSubstr("one run of each"));
    EXPECT_THAT(t.str(), HasSubstr("| fit s (one run) |"));
  }
  EXPECT_EQ(RunRig("evaluate " + out + "/sessions/matte --timing-runs 0 --out " + dir + "/x").status, 2);
  r = RunRig("evaluate " + out + "/sessions/matte --out " + dir + "/again");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(RunRig("evaluate --out " + dir + "/x").status, 2);
  fs::remove_all(dir);
}

TEST(MedianSeconds, TheMiddleRunOrTheMeanOfTheMiddleTwo) {
  EXPECT_DOUBLE_EQ(MedianSeconds({0.3, 9.0, 0.1}), 0.3);  // one slow run (a busy moment) ignored
  EXPECT_DOUBLE_EQ(MedianSeconds({0.4, 0.2, 5.0, 0.3}), 0.35);
  EXPECT_DOUBLE_EQ(MedianSeconds({2.0}), 2.0);
  EXPECT_TRUE(std::isnan(MedianSeconds({})));
}

}  // namespace
}  // namespace rig
