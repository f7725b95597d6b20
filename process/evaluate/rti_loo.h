// The leave-one-out report of model families on a multi-light capture: every family refitted
// without each held-out image (its choices made inside the fold), PSNR in 8 bits against
// bytes per pixel on disk and against fit time, with relight's published figures for the
// shared icon beside ours, as a Markdown table and two charts.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "config/result.h"
#include "process/model/any/rti_fit.h"

namespace rig {

struct RtiLooOptions {
  int every = 1;               // hold out images 0, every, 2·every, ... (1: all)
  int neural_every = 12;       // the neural family is slow to train: fewer folds
  bool neural = true;
  bool harmonic = true;
  PcaChoiceOptions choice;     // the default's
  double large_budget = 12;    // B/px of the "best within 12 B/px" row
  int threads = 2;
};

struct RtiLooRow {
  std::string family;     // "pca-bilinear", "ptm", "neural", ...
  std::string setting;    // what was fitted: "auto within 3.4 B/px", "k 9, 32x32, q85"
  std::string protocol;   // "all 72 refitted", "every 6th refitted", "exact (hat matrix)"
  std::string label;      // short, for charts
  double psnr_mean_mse_db = 0, psnr_median_db = 0;
  double bytes_per_pixel = 0;
  double fit_time_s = 0;  // one fit on all images
  bool is_default = false;
  bool published = false;  // relight's figures, not measured here
};

Result<std::vector<RtiLooRow>> RtiLooTable(
    const RtiCapture& capture, const RtiLooOptions& options,
    const std::function<void(const RtiLooRow&)>& on_row = nullptr);

// relight-cli's figures on the shared icon (../shared/docs/rti-formats.md), all 72 held out.
std::vector<RtiLooRow> RelightPublishedIconRows();

// One console line of a row (progress while the report runs).
std::string RtiLooRowLine(const RtiLooRow& row);

std::string RtiLooMarkdown(const RtiCapture& capture, const std::vector<RtiLooRow>& rows);

// Two PNG charts: <prefix>-psnr-bytes.png and <prefix>-psnr-time.png.
Status WriteRtiLooCharts(const std::vector<RtiLooRow>& rows, const std::string& prefix);

// The whole report: the table (with relight's published rows when the capture is the shared
// icon: 72 images of 402x395), written to `markdown_path`, and the two charts beside it
// (<path without .md>-psnr-bytes.png, -psnr-time.png). Returns the rows.
Result<std::vector<RtiLooRow>> WriteRtiLooReport(
    const RtiCapture& capture, const RtiLooOptions& options, const std::string& markdown_path,
    const std::function<void(const RtiLooRow&)>& on_row = nullptr);

}  // namespace rig
