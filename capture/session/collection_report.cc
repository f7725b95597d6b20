// rig collection report's table: for every session and .lp capture of a collection, the model
// chosen, bytes per pixel, leave-one-out error, fit time and faults, read from what the
// workflow's steps wrote (model reports, evaluation tables, logs, journals, benchmarks).
#include "capture/session/collection_report.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <regex>
#include <sstream>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture/session/session_store.h"
#include "process/evaluate/plot.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string ReadText(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

struct Row {
  std::string name, kind, source, model, loo_protocol, page;
  double bpp = kNaN, loo_psnr_db = kNaN, loo_rms_fit_space = kNaN, eval_loo_rel = kNaN,
         fit_time_s = kNaN, job_wall_s = kNaN, job_rss_mb = kNaN;
  std::vector<std::string> faults;
};

double Num(const std::string& s) {
  try {
    return std::stod(s);
  } catch (const std::exception&) {
    return kNaN;
  }
}

// The first capture group of `re` in `text`, or "".
std::string Find(const std::string& text, const std::string& re, int group = 1) {
  std::smatch m;
  if (std::regex_search(text, m, std::regex(re))) return m[group].str();
  return "";
}

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (char c : line) {
    if (c == '"') quoted = !quoted;
    else if (c == ',' && !quoted) out.push_back(std::exchange(cur, {}));
    else cur += c;
  }
  out.push_back(cur);
  return out;
}

// Snakemake's benchmark file: "s h:m:s max_rss ..." (tab-separated, one run).
void ReadBenchmark(const fs::path& tsv, Row* r) {
  std::istringstream in(ReadText(tsv));
  std::string header, values;
  if (!std::getline(in, header) || !std::getline(in, values)) return;
  std::vector<std::string> h, v;
  std::string x;
  for (std::istringstream a(header); std::getline(a, x, '\t');) h.push_back(x);
  for (std::istringstream a(values); std::getline(a, x, '\t');) v.push_back(x);
  for (size_t i = 0; i < h.size() && i < v.size(); ++i) {
    if (h[i] == "s") r->job_wall_s = Num(v[i]);
    if (h[i] == "max_rss") r->job_rss_mb = Num(v[i]);
  }
}

void ReadSession(const fs::path& dir, const fs::path& entry, const fs::path& session, Row* r) {
  std::error_code ec;
  const fs::path report = session / "model" / "report.md";
  if (fs::exists(report, ec)) {
    const std::string md = ReadText(report);
    std::smatch m;
    static const std::regex kLine(
        "basis (\\S+), method (\\S+), fit space (\\S+); chosen order (\\d+) \\((\\d+) terms\\); "
        "leave-one-out RMS error ([-+0-9.eE]+)[^;]*; ([-+0-9.eE]+) bytes per pixel on disk; "
        "fitted in ([-+0-9.eE]+) s");
    static const std::regex kPcaLine(
        "PCA of the reflectance \\(radiance / lamp radiance\\) of \\d+ radiance maps, "
        "([-+0-9.eE]+) B/px on disk, fitted in ([-+0-9.eE]+) s");
    static const std::regex kPcaChoice(
        "(\\S+) curve, (\\d+) components on a (\\d+)x\\d+ grid at JPEG q(\\d+):");
    if (std::regex_search(md, m, kLine)) {
      r->model = fmt::format("{} {} order {} ({} terms, {} space)", m[1].str(), m[2].str(), m[4].str(),
                             m[5].str(), m[3].str());
      r->loo_rms_fit_space = Num(m[6]);
      r->bpp = Num(m[7]);
      r->fit_time_s = Num(m[8]);
    } else if (std::regex_search(md, m, kPcaLine)) {
      // A PCA session model (model/pca/): its size and time, then the chosen candidate.
      r->bpp = Num(m[1]);
      r->fit_time_s = Num(m[2]);
      std::smatch c;
      if (std::regex_search(md, c, kPcaChoice)) {
        r->model = fmt::format("pca {} curve, {} components, {}x{} grid, q{}", c[1].str(), c[2].str(),
                               c[3].str(), c[3].str(), c[4].str());
      } else {
        r->model = "pca";
      }
    } else {
      r->faults.push_back(report.string() + ": not a model report rig wrote");
    }
    const std::string missing = Find(md, "pixels with missing samples: (\\d+)");
    if (!missing.empty() && missing != "0") r->faults.push_back(missing + " px with missing samples");
  } else {
    r->faults.push_back("no model (logs/fit/" + r->name + ".log)");
  }
  // The evaluation's automatic choice: its leave-one-out relative RMS error.
  const fs::path csv = entry / "evaluate" / "methods.csv";
  if (fs::exists(csv, ec)) {
    std::istringstream in(ReadText(csv));
    std::string line;
    std::getline(in, line);
    const auto header = SplitCsvLine(line);
    auto col = [&](const std::string& n) {
      for (size_t i = 0; i < header.size(); ++i)
        if (header[i] == n) return static_cast<int>(i);
      return -1;
    };
    const int sel = col("selected"), loo = col("loo_relative_rmse");
    while (std::getline(in, line)) {
      const auto f = SplitCsvLine(line);
      if (sel >= 0 && loo >= 0 && sel < static_cast<int>(f.size()) && f[sel] == "1" &&
          loo < static_cast<int>(f.size())) {
        r->eval_loo_rel = Num(f[loo]);
        break;
      }
    }
  }
  // Device faults and damaged frames the capture journaled; poses the merge could not do.
  int faults = 0, damaged = 0;
  std::istringstream journal(ReadText(session / "journal.jsonl"));
  for (std::string line; std::getline(journal, line);) {
    auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!j.is_object()) continue;
    const std::string ev = j.value("event", "");
    faults += ev == "fault";
    damaged += ev == "frame_damaged";
  }
  if (faults) r->faults.push_back(fmt::format("{} device fault(s) journaled", faults));
  if (damaged) r->faults.push_back(fmt::format("{} damaged frame(s)", damaged));
  const std::string merged = Find(ReadText(dir / "logs" / "merge" / (r->name + ".log")),
                                  "radiance maps: \\d+ merged, \\d+ up to date, (\\d+) failed");
  if (!merged.empty() && merged != "0") r->faults.push_back(merged + " pose(s) failed to merge");
}

void ReadLpRow(const fs::path& dir, const fs::path& entry, Row* r) {
  std::error_code ec;
  const fs::path report = entry / "fit.md";
  const fs::path log = dir / "logs" / "fit" / (r->name + ".log");
  if (!fs::exists(report, ec) || !fs::exists(entry / "model" / "info.json", ec)) {
    r->faults.push_back("no model (logs/fit/" + r->name + ".log)");
  }
  const std::string md = ReadText(report), out = ReadText(log);
  std::smatch m;
  // "rig fit: wrote OUT (2.33 B/px): pca-bilinear, <choice>; masked ...; load 0.50 s, fit 2.00 s"
  if (std::regex_search(out, m, std::regex("rig fit: wrote \\S+ \\(([-+0-9.eE]+) B/px\\): ([^;]+);"))) {
    r->bpp = Num(m[1]);
    r->model = m[2].str().substr(0, m[2].str().find(':'));  // the family and size, not the why
    const std::string fit = Find(out, "load [-+0-9.eE]+ s, fit ([-+0-9.eE]+) s");
    if (!fit.empty()) {
      r->fit_time_s = Num(fit);
    } else if (std::regex_search(out, m, std::regex("sample ([-+0-9.eE]+) s, choice ([-+0-9.eE]+) s, "
                                                    "planes ([-+0-9.eE]+) s"))) {
      r->fit_time_s = Num(m[1]) + Num(m[2]) + Num(m[3]);
    }
  }
  // The leave-one-out report of rig evaluate --lp (the default model's row is in bold) ...
  const std::string loo = ReadText(entry / "evaluate" / "rti-loo.md");
  if (std::regex_search(loo, m, std::regex("\\| \\*\\*[^|]*\\*\\* \\| [^|]* \\| ([^|]*) \\| "
                                           "([-+0-9.eE]+) / ([-+0-9.eE]+) \\|"))) {
    r->loo_psnr_db = Num(m[2]);
    r->loo_protocol = "leave-one-out (rig evaluate --lp: " + std::string(m[1].str()) + "), mean-MSE PSNR";
  } else {
    // ... else the fit's own estimate at the lights its choice held out.
    const std::string held = Find(md, "([-+0-9.eE]+) dB at held-out lights \\(([^)]*)\\)");
    if (!held.empty()) {
      r->loo_psnr_db = Num(held);
      r->loo_protocol = "the fit's choice: " + Find(md, "dB at held-out lights \\(([^)]*)\\)");
    }
  }
  const std::string masked = Find(out, "masked ([-+0-9.eE]+)% of samples");
  if (!masked.empty() && Num(masked) > 0) r->faults.push_back(masked + "% of samples clipped or black");
}

std::string Cell(double v, int digits) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : std::string();
}

std::string Html(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else if (c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

std::string CsvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

struct CollectionTexts {
  std::string md, csv, html;
};

// Every entry of results/: its source (a session or an .lp), read from what the workflow's
// steps wrote.
Result<std::vector<Row>> CollectRows(const fs::path& d) {
  std::error_code ec;
  const fs::path results = d / "results";
  if (!fs::is_directory(results, ec)) {
    return MakeError(ErrorCode::kInvalidInput, results.string(),
                                               "no results: run the workflow (snakemake) in {} first", d.string());
  }
  std::vector<Row> rows;
  std::vector<fs::path> entries;
  for (const auto& e : fs::directory_iterator(results, ec))
    if (e.is_directory()) entries.push_back(e.path());
  std::sort(entries.begin(), entries.end());
  for (const auto& entry : entries) {
    const fs::path src = entry / "source";
    if (!fs::is_symlink(src, ec)) continue;
    Row r;
    r.name = entry.filename().string();
    r.source = fs::read_symlink(src, ec).string();
    if (fs::is_directory(src, ec) && fs::exists(src / "session.toml", ec)) {
      r.kind = "session";
      ReadSession(d, entry, fs::path(r.source), &r);
    } else if (fs::is_regular_file(src, ec)) {
      r.kind = "lp";
      ReadLpRow(d, entry, &r);
    } else {
      r.kind = "missing";
      r.faults.push_back("the source is gone: " + r.source);
    }
    ReadBenchmark(d / "benchmarks" / "fit" / (r.name + ".tsv"), &r);
    if (fs::exists(entry / "view" / "index.html", ec)) r.page = "results/" + r.name + "/view/index.html";
    else if (fs::exists(entry / "render.png", ec)) r.page = "results/" + r.name + "/render.png";
    rows.push_back(std::move(r));
  }
  if (rows.empty()) {
    return MakeError(ErrorCode::kInvalidInput, results.string(), "no entries (results/<name>/source)");
  }
  return rows;
}

// The table as Markdown, CSV and an HTML page linking every entry's page.
CollectionTexts ReportTexts(const fs::path& d, const std::vector<Row>& rows) {
  CollectionTexts t;
  auto faults = [](const Row& r) {
    std::string s;
    for (const auto& f : r.faults) s += (s.empty() ? "" : "; ") + f;
    return s.empty() ? std::string("none") : s;
  };
  std::string& md = t.md;
  md = fmt::format(
      "# Collection {}\n\n{} entries. Sessions: the model rig process chose (model/report.md), its "
      "leave-one-out RMS error in the fit space, and the leave-one-out relative RMS error of "
      "`rig evaluate`'s automatic choice (methods.csv). .lp captures: the model rig fit chose, "
      "and its PSNR at held-out lights ({}). Job wall time and peak memory: Snakemake's "
      "benchmark of the fit job.\n\n"
      "| entry | kind | model chosen | B/px | leave-one-out | fit (s) | fit job (s, MB) | faults | page |\n"
      "|---|---|---|---|---|---|---|---|---|\n",
      fs::absolute(d).lexically_normal().string(), rows.size(),
      "rig evaluate --lp's leave-one-out when it ran, else the fit's own hold-out");
  std::string& csv = t.csv;
  csv =
      "name,kind,source,model,bytes_per_pixel,loo_psnr_db,loo_psnr_protocol,loo_rms_fit_space,"
      "evaluate_loo_relative_rmse,fit_time_s,fit_job_wall_s,fit_job_max_rss_mb,faults,page\n";
  std::string& html = t.html;
  html = fmt::format(
      "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>rig collection</title>\n"
      "<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}"
      "td,th{{border:1px solid #ccc;padding:4px 8px;text-align:left}}</style></head><body>\n"
      "<h1>Collection</h1>\n<p>{} entries; <a href=\"collection.md\">table</a>, "
      "<a href=\"collection.csv\">CSV</a>.</p>\n<p><img src=\"collection.png\" alt=\"chart\" width=\"720\"></p>\n"
      "<table><tr><th>entry</th><th>kind</th><th>model chosen</th><th>B/px</th><th>leave-one-out</th>"
      "<th>fit (s)</th><th>faults</th></tr>\n",
      rows.size());
  for (const auto& r : rows) {
    std::string loo;
    if (std::isfinite(r.loo_psnr_db)) loo = fmt::format("{:.2f} dB PSNR", r.loo_psnr_db);
    if (std::isfinite(r.loo_rms_fit_space)) loo = fmt::format("RMS {:.4g} (fit space)", r.loo_rms_fit_space);
    if (std::isfinite(r.eval_loo_rel))
      loo += fmt::format("{}evaluate: {:.4f} relative", loo.empty() ? "" : "; ", r.eval_loo_rel);
    const std::string page = r.page.empty() ? "" : "[page](../" + r.page + ")";
    md += fmt::format("| {} | {} | {} | {} | {} | {} | {} / {} | {} | {} |\n", r.name, r.kind, r.model,
                      Cell(r.bpp, 2), loo, Cell(r.fit_time_s, 2), Cell(r.job_wall_s, 2),
                      Cell(r.job_rss_mb, 0), faults(r), page);
    csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", CsvField(r.name), r.kind,
                       CsvField(r.source), CsvField(r.model), Cell(r.bpp, 3), Cell(r.loo_psnr_db, 3),
                       CsvField(r.loo_protocol), Cell(r.loo_rms_fit_space, 6), Cell(r.eval_loo_rel, 6),
                       Cell(r.fit_time_s, 3), Cell(r.job_wall_s, 3), Cell(r.job_rss_mb, 1),
                       CsvField(faults(r)), CsvField(r.page));
    const std::string name = r.page.empty() ? Html(r.name)
                                            : "<a href=\"../" + Html(r.page) + "\">" + Html(r.name) + "</a>";
    html += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                        name, r.kind, Html(r.model), Cell(r.bpp, 2), Html(loo), Cell(r.fit_time_s, 2),
                        Html(faults(r)));
  }
  html += "</table>\n</body></html>\n";
  return t;
}

// The chart: every entry's fit time against its bytes per pixel, one series per kind, as PNG.
Result<std::vector<uint8_t>> ReportChart(const std::vector<Row>& rows) {
  std::map<std::string, PlotSeries> series;
  for (const auto& r : rows) {
    if (!std::isfinite(r.bpp) || !std::isfinite(r.fit_time_s)) continue;
    PlotSeries& s = series[r.kind];
    s.label = r.kind == "lp" ? ".lp captures" : "sessions";
    s.line = false;
    s.x.push_back(r.bpp);
    s.y.push_back(std::max(r.fit_time_s, 1e-3));
    s.point_labels.push_back(r.name);
  }
  std::vector<PlotSeries> all;
  for (auto& [k, s] : series) all.push_back(std::move(s));
  PlotOptions po;
  po.title = "Collection: fit time against model size";
  po.x_label = "bytes per pixel on disk";
  po.y_label = "fit time (s)";
  po.log_x = po.log_y = true;
  po.notes = {fmt::format("{} entries; one point per model (rig's own fit time)", rows.size())};
  cv::Mat chart = DrawPlot(all, {}, po);
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", chart, png)) {
    return MakeError(ErrorCode::kIo, "collection.png", "cannot encode");
  }
  return png;
}

}  // namespace

Status WriteCollectionReport(const fs::path& d, std::string* markdown, fs::path* written) {
  RIG_ASSIGN_OR_RETURN(std::vector<Row> rows, CollectRows(d));
  const CollectionTexts t = ReportTexts(d, rows);
  RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> png, ReportChart(rows));
  std::error_code ec;
  const fs::path out = d / "report";
  fs::create_directories(out, ec);
  for (const auto& [name, text] : {std::pair<std::string, std::string>{"collection.md", t.md},
                                   {"collection.csv", t.csv}, {"index.html", t.html}}) {
    RIG_TRY(WriteFileAtomic(out / name, text));
  }
  RIG_TRY(WriteFileAtomic(out / "collection.png", png));
  *markdown = t.md;
  *written = out;
  return Ok();
}

}  // namespace rig
