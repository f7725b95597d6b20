// rig status: what a running `rig daemon` is doing (GET /api/status).
#include <cstdio>
#include <map>
#include <set>
#include <utility>

#include "capture/service/client.h"
#include "rig/commands/command.h"
#include "rig/commands/daemon_client.h"

namespace rig {
namespace {

std::string Duration(const nlohmann::json& s) {
  if (!s.is_number()) return "-";
  const int t = static_cast<int>(s.get<double>() + 0.5);
  return t >= 60 ? fmt::format("{} min {} s", t / 60, t % 60) : fmt::format("{} s", t);
}

// The grid as text, the highest row first: '#' stored, '>' next, '.' to come; on an adaptive
// grid 'o' allowed and not chosen, ' ' not chosen once the choice stopped.
std::string GridDiagram(const nlohmann::json& grid) {
  std::set<double> hs, vs;
  std::map<std::pair<double, double>, char> mark;
  for (const auto& p : grid) {
    if (!p.contains("h_deg") || !p["h_deg"].is_number() || !p.contains("v_deg") ||
        !p["v_deg"].is_number() || !p.contains("state") || !p["state"].is_string())
      continue;
    const double h = p["h_deg"].get<double>(), v = p["v_deg"].get<double>();
    hs.insert(h);
    vs.insert(v);
    const std::string st = p["state"].get<std::string>();
    mark[{h, v}] = st == "done" ? '#' : st == "next" ? '>' : st == "allowed" ? 'o' : st == "skipped" ? ' ' : '.';
  }
  if (hs.empty() || hs.size() > 200) return "";
  std::string out;
  for (auto v = vs.rbegin(); v != vs.rend(); ++v) {
    out += fmt::format("{:>6}", fmt::format("{:g}°", *v));
    for (double h : hs) {
      auto it = mark.find({h, *v});
      out += fmt::format(" {:>3}", std::string(1, it == mark.end() ? ' ' : it->second));
    }
    out += "\n";
  }
  out += "      ";
  for (double h : hs) out += fmt::format(" {:>3}", fmt::format("{:g}", h));
  return out + "  (horizontal °)\n";
}

}  // namespace

int RunStatus(int argc, char** argv) {
  CLI::App app{"What the capture daemon is doing: its state (idle, capturing, processing, "
               "stopping, fault), the job and session, the pose, frames stored, time "
               "remaining, the model's progress and the last fault. Exit 1 when no daemon "
               "answers.",
               "rig status"};
  DaemonTarget target;
  bool json = false;
  app.add_option("--daemon", target.url,
                 fmt::format("the daemon's URL (default: $RIG_DAEMON, else http://127.0.0.1:{})",
                             7130));
  app.add_option("--token-file", target.token_file, "the daemon's token (default: $RIG_DAEMON_TOKEN_FILE)");
  app.add_flag("--json", json, "print the daemon's JSON as it is");
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  auto daemon = ResolveDaemon(target, /*fallback_default=*/true);
  if (!daemon.ok()) return ReportError("status", daemon.error());
  DaemonClient client(**daemon, 5);
  auto s = client.Get("/api/status");
  if (!s.ok()) {
    ReportError("status", s.error());
    return 1;
  }
  if (json) {
    std::printf("%s\n", s->dump(2).c_str());
    return 0;
  }
  const nlohmann::json& st = *s;
  const nlohmann::json& job = st["job"].is_null() ? st["last_job"] : st["job"];
  std::string line = fmt::format("daemon {}: {}{}", (*daemon)->Url(), st["state"].get<std::string>(),
                                 st["held"].get<bool>() ? " (queue held: 'resume' releases it)" : "");
  if (!job.is_null())
    line += fmt::format("; {}job {} {} {}", st["job"].is_null() ? "last " : "", job["id"].get<int>(),
                        job["kind"].get<std::string>(), job["state"].get<std::string>());
  std::printf("%s\n", line.c_str());
  if (!st["session"].is_null()) std::printf("session %s\n", st["session"].get<std::string>().c_str());
  if (!st["frames"].is_null()) {
    std::string pose = st["pose"].is_null()
                           ? std::string("every pose stored")
                           : fmt::format("pose {} ({} of {})", st["pose"]["name"].get<std::string>(),
                                         st["pose"]["number"].get<int>(), st["pose"]["total"].get<int>());
    std::printf("%s  frames %d of %d stored  remaining %s\n", pose.c_str(),
                st["frames"]["stored"].get<int>(), st["frames"]["total"].get<int>(),
                Duration(st["eta_s"]).c_str());
  }
  if (st.contains("choice") && st["choice"].is_object()) {
    const nlohmann::json& c = st["choice"];
    std::string line = fmt::format("adaptive grid: {} of at most {} poses chosen ({} allowed)",
                                   c.value("chosen", 0), c.value("max_poses", 0), c.value("allowed", 0));
    if (c["predicted_rms"].is_number() && c["floor_rms"].is_number())
      line += fmt::format("; predicted error {:.2f} codes ({:.2f} with every pose)",
                          c["predicted_rms"].get<double>(), c["floor_rms"].get<double>());
    if (c["stopped"].is_string()) line += "; stopped: " + c["stopped"].get<std::string>();
    std::printf("%s\n", line.c_str());
  }
  if (st.contains("grid") && st["grid"].is_array() && !st["grid"].empty()) {
    const bool adaptive = st.contains("choice") && st["choice"].is_object();
    std::printf("lamp poses (# stored, > next, . to come%s):\n%s", adaptive ? ", o allowed" : "",
                GridDiagram(st["grid"]).c_str());
  }
  if (!st["model"].is_null())
    std::printf("model: %d of %d radiance maps, %s\n", st["model"]["radiance_maps"].get<int>(),
                st["model"]["poses"].get<int>(), st["model"]["phase"].get<std::string>().c_str());
  if (!st["last_fault"].is_null())
    std::printf("last fault (job %d): %s\n", st["last_fault"]["job"].get<int>(),
                st["last_fault"]["error"].get<std::string>().c_str());
  if (!job.is_null() && job.contains("error") && job["state"] != "fault")
    std::printf("job %d: %s\n", job["id"].get<int>(), job["error"].get<std::string>().c_str());
  if (!st["queue"].empty()) std::printf("queue: %zu job(s)\n", st["queue"].size());
  return 0;
}

}  // namespace rig
