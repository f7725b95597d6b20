// The capture service's HTTP+JSON API and status page (cpp-httplib).
#include "capture/service/http_server.h"

#include <arpa/inet.h>

#include <chrono>
#include <thread>

#include <httplib.h>

#include "config/log.h"

namespace rig {
namespace {

int HttpStatusOf(const Error& e) {
  switch (e.code) {
    case ErrorCode::kInvalidInput: return 400;
    case ErrorCode::kNotFound: return 404;
    case ErrorCode::kBusy: return 409;
    default: return 500;
  }
}

void SendJson(httplib::Response& res, const nlohmann::json& j, int status = 200) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(j.dump(), "application/json");
}

void SendError(httplib::Response& res, const Error& e) {
  SendJson(res, {{"error", e.ToString()}, {"code", ErrorCodeName(e.code)}}, HttpStatusOf(e));
}

// Compares in time independent of where the strings differ.
bool SameSecret(const std::string& a, const std::string& b) {
  if (a.size() != b.size() || b.empty()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

Result<nlohmann::json> BodyJson(const httplib::Request& req, bool allow_empty) {
  if (req.body.empty() && allow_empty) return nlohmann::json::object();
  auto j = nlohmann::json::parse(req.body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return MakeError(ErrorCode::kInvalidInput, "request", "the body is not JSON");
  return j;
}

}  // namespace

bool IsLoopbackHost(const std::string& host) {
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

Status CheckListenOptions(const HttpOptions& o) {
  if (IsLoopbackHost(o.host)) return Ok();
  if (!o.allow_remote)
    return MakeError(ErrorCode::kInvalidInput, "--listen",
                     "'{}' is not a loopback address: listening there needs --allow-remote and "
                     "--token-file (anyone who reaches the port could move the rig)",
                     o.host);
  if (o.token.empty())
    return MakeError(ErrorCode::kInvalidInput, "--token-file",
                     "--allow-remote needs a token: every request must then carry "
                     "'Authorization: Bearer TOKEN'");
  return Ok();
}

Result<std::pair<std::string, int>> ParseListenAddress(const std::string& text) {
  std::string host = "127.0.0.1", port = text;
  if (!text.empty() && text[0] == '[') {
    size_t close = text.find(']');
    if (close == std::string::npos || close + 1 >= text.size() || text[close + 1] != ':')
      return MakeError(ErrorCode::kInvalidInput, "--listen", "'{}': expected [ADDRESS]:PORT", text);
    host = text.substr(1, close - 1);
    port = text.substr(close + 2);
  } else if (size_t colon = text.rfind(':'); colon != std::string::npos) {
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
  }
  char* end = nullptr;
  long p = std::strtol(port.c_str(), &end, 10);
  if (port.empty() || *end != '\0' || p < 0 || p > 65535 || host.empty())
    return MakeError(ErrorCode::kInvalidInput, "--listen", "'{}': expected HOST:PORT (port 0-65535)", text);
  return std::make_pair(host, static_cast<int>(p));
}

HttpServer::HttpServer(CaptureService& service, HttpOptions options)
    : service_(service), options_(std::move(options)), server_(std::make_unique<httplib::Server>()) {}

HttpServer::~HttpServer() { Stop(); }

Status HttpServer::Start() {
  RIG_TRY(CheckListenOptions(options_));
  Routes();
  const std::string where = fmt::format("{}:{}", options_.host, options_.port);
  if (options_.port == 0) {
    port_ = server_->bind_to_any_port(options_.host);
    if (port_ <= 0)
      return MakeError(ErrorCode::kIo, options_.host, "cannot listen on any port");
  } else {
    if (!server_->bind_to_port(options_.host, options_.port))
      return MakeError(ErrorCode::kBusy, where, "cannot listen (address in use, or not this host's)");
    port_ = options_.port;
  }
  thread_ = std::thread([this] { server_->listen_after_bind(); });
  Log("rig")->info("daemon listening url=http://{}:{}/ token={}", options_.host, port_,
                   options_.token.empty() ? "none" : "required");
  return Ok();
}

void HttpServer::Stop() {
  stopping_ = true;
  if (server_) server_->stop();
  if (thread_.joinable()) thread_.join();
}

void HttpServer::Routes() {
  httplib::Server& s = *server_;
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    // The page itself holds no data; everything it shows comes through /api/ with the token.
    if (options_.token.empty() || req.path.rfind("/api/", 0) != 0)
      return httplib::Server::HandlerResponse::Unhandled;
    const std::string auth = req.get_header_value("Authorization");
    const std::string prefix = "Bearer ";
    if (auth.rfind(prefix, 0) == 0 && SameSecret(auth.substr(prefix.size()), options_.token))
      return httplib::Server::HandlerResponse::Unhandled;
    res.set_header("WWW-Authenticate", "Bearer realm=\"rig\"");
    SendJson(res, {{"error", "this daemon needs 'Authorization: Bearer TOKEN' (its --token-file)"}},
             401);
    return httplib::Server::HandlerResponse::Handled;
  });

  s.Get("/", [](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(StatusPageHtml(), "text/html; charset=utf-8");
  });
  s.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    SendJson(res, service_.StatusJson());
  });
  s.Get("/api/jobs", [this](const httplib::Request&, httplib::Response& res) {
    nlohmann::json jobs = nlohmann::json::array();
    for (const auto& j : service_.Jobs()) jobs.push_back(j.ToJson());
    SendJson(res, {{"jobs", jobs}});
  });
  s.Get(R"(/api/jobs/(\d+))", [this](const httplib::Request& req, httplib::Response& res) {
    auto job = service_.Job(std::atoi(req.matches[1].str().c_str()));
    if (!job) return SendError(res, MakeError(ErrorCode::kNotFound, "job", "no job {}", req.matches[1].str()));
    SendJson(res, job->ToJson());
  });
  s.Post("/api/jobs", [this](const httplib::Request& req, httplib::Response& res) {
    auto body = BodyJson(req, false);
    if (!body.ok()) return SendError(res, body.error());
    auto job = service_.Submit(*body);
    if (!job.ok()) return SendError(res, job.error());
    SendJson(res, job->ToJson(), 202);
  });
  s.Post("/api/stop", [this](const httplib::Request&, httplib::Response& res) {
    SendJson(res, service_.Stop());
  });
  s.Post("/api/resume", [this](const httplib::Request& req, httplib::Response& res) {
    auto body = BodyJson(req, true);
    if (!body.ok()) return SendError(res, body.error());
    std::optional<fs::path> session;
    if (body->is_object() && body->contains("session") && (*body)["session"].is_string())
      session = fs::path((*body)["session"].get<std::string>());
    bool process = true;
    if (body->is_object() && body->contains("process") && (*body)["process"].is_boolean())
      process = (*body)["process"].get<bool>();
    auto r = service_.Resume(session, process);
    if (!r.ok()) return SendError(res, r.error());
    SendJson(res, *r, (*r)["job"].is_null() ? 200 : 202);
  });
  s.Get("/api/journal", [this](const httplib::Request& req, httplib::Response& res) {
    size_t since = 0;
    if (req.has_param("since")) since = std::strtoull(req.get_param_value("since").c_str(), nullptr, 10);
    SendJson(res, service_.Journal(since));
  });
  s.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
    size_t since = 0;
    if (req.has_param("since")) since = std::strtoull(req.get_param_value("since").c_str(), nullptr, 10);
    auto next = std::make_shared<size_t>(since);
    auto last_state = std::make_shared<std::string>();
    res.set_header("Cache-Control", "no-store");
    res.set_chunked_content_provider(
        "text/event-stream", [this, next, last_state](size_t, httplib::DataSink& sink) {
          if (stopping_ || service_.shutting_down()) {
            sink.done();
            return true;
          }
          std::string out;
          nlohmann::json j = service_.Journal(*next);
          for (const auto& r : j["records"])
            out += fmt::format("id: {}\nevent: journal\ndata: {}\n\n", (*next)++, r.dump());
          nlohmann::json st = service_.StatusJson();
          nlohmann::json brief = {{"state", st["state"]}, {"frames", st["frames"]},
                                  {"pose", st["pose"]}, {"eta_s", st["eta_s"]}};
          std::string b = brief.dump();
          if (b != *last_state) {
            out += "event: status\ndata: " + b + "\n\n";
            *last_state = b;
          }
          if (!out.empty() && !sink.write(out.data(), out.size())) return false;
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
          return true;
        });
  });
  auto image = [](httplib::Response& res, const std::vector<uint8_t>& jpeg, const char* what) {
    if (jpeg.empty()) return SendJson(res, {{"error", fmt::format("no {} yet", what)}}, 404);
    res.set_header("Cache-Control", "no-store");
    res.set_content(reinterpret_cast<const char*>(jpeg.data()), jpeg.size(), "image/jpeg");
  };
  s.Get("/api/preview/frame.jpg", [this, image](const httplib::Request&, httplib::Response& res) {
    image(res, service_.PreviewFrame(), "frame");
  });
  s.Get("/api/preview/radiance.jpg", [this, image](const httplib::Request&, httplib::Response& res) {
    image(res, service_.PreviewRadiance(), "radiance map");
  });
}

}  // namespace rig
