// The capture service's HTTP+JSON API and status page (cpp-httplib).
#include "capture/service/http_server.h"

#include <arpa/inet.h>
#include <sys/socket.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <optional>
#include <thread>

#include <httplib.h>

#include "capture/service/connection_guard.h"
#include "capture/service/request_checks.h"
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

// What the page and every answer carry: no framing, no sniffing, no referrer, and the page's
// scripts, styles, images and requests from the daemon alone (previews as blob: URLs).
const httplib::Headers& SecurityHeaders() {
  static const httplib::Headers kHeaders = {
      {"Content-Security-Policy",
       "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' blob:; "
       "connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'none'; "
       "frame-ancestors 'none'"},
      {"X-Frame-Options", "DENY"},
      {"X-Content-Type-Options", "nosniff"},
      {"Referrer-Policy", "no-referrer"}};
  return kHeaders;
}

std::optional<std::string> Header(const httplib::Request& req, const char* name) {
  if (!req.has_header(name)) return std::nullopt;
  return req.get_header_value(name);
}

RequestFacts FactsOf(const httplib::Request& req) {
  RequestFacts f;
  f.method = req.method;
  f.path = req.path;
  f.host = Header(req, "Host");
  f.origin = Header(req, "Origin");
  f.content_type = Header(req, "Content-Type");
  f.content_length = Header(req, "Content-Length");
  f.transfer_encoding = Header(req, "Transfer-Encoding");
  f.sec_fetch_site = Header(req, "Sec-Fetch-Site");
  f.sec_fetch_mode = Header(req, "Sec-Fetch-Mode");
  f.authorization = Header(req, "Authorization");
  f.page_token = Header(req, kPageTokenHeader);
  return f;
}

void SendError(httplib::Response& res, const Error& e) {
  SendJson(res, {{"error", e.ToString()}, {"code", ErrorCodeName(e.code)}}, HttpStatusOf(e));
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

namespace {

using Handler = std::function<void(const httplib::Request&, httplib::Response&)>;

// cpp-httplib's server with its listening socket at hand: cpp-httplib listens with a backlog
// of 5, so that a burst of connections (a flood, or 40 page loads) has the kernel drop SYNs
// and the clients retry a second later; listen() again takes the system's maximum instead.
class ListeningServer : public httplib::Server {
 public:
  void WidenBacklog() { ::listen(svr_sock_, SOMAXCONN); }
};

// The handler, with the connection marked as answering (no read deadline while it runs).
Handler Guarded(std::atomic<ConnectionGuard*>& guard, Handler h) {
  return [&guard, h = std::move(h)](const httplib::Request& req, httplib::Response& res) {
    if (ConnectionGuard* g = guard.load()) g->Handling(req.remote_addr, req.remote_port);
    h(req, res);
  };
}

size_t SinceParam(const httplib::Request& req) {
  if (!req.has_param("since")) return 0;
  return std::strtoull(req.get_param_value("since").c_str(), nullptr, 10);
}

}  // namespace

HttpServer::HttpServer(CaptureService& service, HttpOptions options)
    : service_(service),
      options_(std::move(options)),
      page_token_(RandomToken()),
      server_(std::make_unique<ListeningServer>()) {}

HttpServer::~HttpServer() { Stop(); }

Status HttpServer::Start() {
  RIG_TRY(CheckListenOptions(options_));
  for (const std::string& h : options_.allowed_hosts)
    if (!ParseHostHeader(h))
      return MakeError(ErrorCode::kInvalidInput, "--allowed-host", "'{}': expected NAME or NAME:PORT", h);
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
  static_cast<ListeningServer&>(*server_).WidenBacklog();
  thread_ = std::thread([this] {
    server_->listen_after_bind();
    listen_ended_ = true;
  });
  WaitUntilListening();
  Log("rig")->info("daemon listening url=http://{}:{}/ token={}", options_.host, port_,
                   options_.token.empty() ? "none" : "required");
  return Ok();
}

// cpp-httplib's stop() does nothing until its loop has marked itself running (0.11: is_running_
// is set inside listen_after_bind), so a Stop right after Start would leave the loop running
// and the join waiting forever: the loop is waited for first.
void HttpServer::WaitUntilListening() {
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!server_->is_running() && !listen_ended_ && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void HttpServer::Stop() {
  stopping_ = true;
  if (server_ && thread_.joinable()) WaitUntilListening();
  if (server_) server_->stop();
  if (thread_.joinable()) thread_.join();
  guard_ = nullptr;  // cpp-httplib deleted it when listening ended
}

bool HttpServer::PreRouting(const httplib::Request& req, httplib::Response& res) {
  if (ConnectionGuard* g = guard_.load()) g->HeadersRead(req.remote_addr, req.remote_port);
  RequestPolicy policy;
  policy.listen_host = options_.host;
  policy.port = port_;
  policy.allowed_hosts = options_.allowed_hosts;
  policy.bearer_token = options_.token;
  policy.page_token = page_token_;
  auto refusal = CheckRequest(FactsOf(req), policy);
  if (!refusal) return false;
  ++refused_;
  if (refusal->status == 401) res.set_header("WWW-Authenticate", "Bearer realm=\"rig\"");
  // A refused body is not read: the connection closes after the answer.
  res.set_header("Connection", "close");
  if (ConnectionGuard* g = guard_.load()) g->Refused(req.remote_addr, req.remote_port);
  Log("rig")->warn("daemon refused {} {} from {}:{}: {} {}", req.method.substr(0, 16),
                   req.path.substr(0, 200), req.remote_addr, req.remote_port, refusal->status,
                   refusal->error);
  SendJson(res, {{"error", refusal->error}}, refusal->status);
  return true;
}

void HttpServer::Routes() {
  httplib::Server& s = *server_;
  s.set_read_timeout(static_cast<time_t>(std::ceil(options_.request_timeout_s)));
  s.set_write_timeout(static_cast<time_t>(std::ceil(options_.request_timeout_s)));
  s.set_keep_alive_timeout(static_cast<time_t>(std::ceil(options_.request_timeout_s)));
  s.set_payload_max_length(kMaxBodyBytes);
  s.set_default_headers(SecurityHeaders());
  s.new_task_queue = [this]() -> httplib::TaskQueue* {
    ConnectionLimits limits;
    limits.max_connections = options_.max_connections;
    limits.max_streams = options_.max_streams;
    limits.request_timeout_s = options_.request_timeout_s;
    limits.max_body_bytes = kMaxBodyBytes;
    auto* g = new ConnectionGuard(port_, limits);
    guard_ = g;
    return g;
  };
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    return PreRouting(req, res) ? httplib::Server::HandlerResponse::Handled
                                : httplib::Server::HandlerResponse::Unhandled;
  });
  s.set_logger([this](const httplib::Request& req, const httplib::Response&) {
    if (ConnectionGuard* g = guard_.load()) g->Answered(req.remote_addr, req.remote_port);
  });
  s.set_exception_handler([](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "unknown exception";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    Log("rig")->error("daemon: {} {}: {}", req.method.substr(0, 16), req.path.substr(0, 200), what);
    SendJson(res, {{"error", fmt::format("internal error answering {}", req.path.substr(0, 200))}}, 500);
  });
  PageRoutes();
  ApiRoutes();
  EventRoutes();
}

void HttpServer::PageRoutes() {
  httplib::Server& s = *server_;
  s.Get("/", Guarded(guard_, [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(StatusPageHtml(page_token_), "text/html; charset=utf-8");
  }));
  for (const auto& [name, content] : StatusPageAssets()) {
    if (name == "index.html") continue;
    const std::string type = name.size() > 3 && name.substr(name.size() - 3) == ".js"
                                 ? "text/javascript; charset=utf-8"
                                 : "text/css; charset=utf-8";
    const std::string* body = &content;
    s.Get("/" + name, Guarded(guard_, [body, type](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-store");
      res.set_content(*body, type.c_str());
    }));
  }
}

void HttpServer::ApiRoutes() {
  httplib::Server& s = *server_;
  s.Get("/api/status", Guarded(guard_, [this](const httplib::Request&, httplib::Response& res) {
    SendJson(res, service_.StatusJson());
  }));
  s.Get("/api/jobs", Guarded(guard_, [this](const httplib::Request&, httplib::Response& res) {
    nlohmann::json jobs = nlohmann::json::array();
    for (const auto& j : service_.Jobs()) jobs.push_back(j.ToJson());
    SendJson(res, {{"jobs", jobs}});
  }));
  s.Get(R"(/api/jobs/(\d{1,9}))", Guarded(guard_, [this](const httplib::Request& req, httplib::Response& res) {
    auto job = service_.Job(std::atoi(req.matches[1].str().c_str()));
    if (!job) return SendError(res, MakeError(ErrorCode::kNotFound, "job", "no job {}", req.matches[1].str()));
    SendJson(res, job->ToJson());
  }));
  s.Post("/api/jobs", Guarded(guard_, [this](const httplib::Request& req, httplib::Response& res) {
    auto body = BodyJson(req, false);
    if (!body.ok()) return SendError(res, body.error());
    auto job = service_.Submit(*body);
    if (!job.ok()) return SendError(res, job.error());
    SendJson(res, job->ToJson(), 202);
  }));
  s.Post("/api/stop", Guarded(guard_, [this](const httplib::Request&, httplib::Response& res) {
    SendJson(res, service_.Stop());
  }));
  s.Post("/api/resume", Guarded(guard_, [this](const httplib::Request& req, httplib::Response& res) {
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
  }));
  s.Get("/api/journal", Guarded(guard_, [this](const httplib::Request& req, httplib::Response& res) {
    SendJson(res, service_.Journal(SinceParam(req)));
  }));
  auto image = [](httplib::Response& res, const std::vector<uint8_t>& jpeg, const char* what) {
    if (jpeg.empty()) return SendJson(res, {{"error", fmt::format("no {} yet", what)}}, 404);
    res.set_header("Cache-Control", "no-store");
    res.set_content(reinterpret_cast<const char*>(jpeg.data()), jpeg.size(), "image/jpeg");
  };
  s.Get("/api/preview/frame.jpg", Guarded(guard_, [this, image](const httplib::Request&, httplib::Response& res) {
    image(res, service_.PreviewFrame(), "frame");
  }));
  s.Get("/api/preview/radiance.jpg", Guarded(guard_, [this, image](const httplib::Request&, httplib::Response& res) {
    image(res, service_.PreviewRadiance(), "radiance map");
  }));
}

namespace {

// One look at the journal and the status for an event stream: what is new since the last.
std::string EventsSince(CaptureService& service, size_t& next, std::string& last_state) {
  std::string out;
  nlohmann::json j = service.Journal(next);
  for (const auto& r : j["records"]) out += fmt::format("id: {}\nevent: journal\ndata: {}\n\n", next++, r.dump());
  nlohmann::json st = service.StatusJson();
  nlohmann::json brief = {{"state", st["state"]}, {"frames", st["frames"]},
                          {"pose", st["pose"]}, {"eta_s", st["eta_s"]}};
  std::string b = brief.dump();
  if (b != last_state) {
    out += "event: status\ndata: " + b + "\n\n";
    last_state = b;
  }
  return out;
}

}  // namespace

void HttpServer::EventRoutes() {
  server_->Get("/api/events", Guarded(guard_, [this](const httplib::Request& req, httplib::Response& res) {
    ConnectionGuard* guard = guard_.load();
    if (guard && !guard->BeginStream(req.remote_addr, req.remote_port))
      return SendJson(res, {{"error", fmt::format("{} event streams are open (at most {}); close one "
                                                  "or poll /api/status", options_.max_streams,
                                                  options_.max_streams)}}, 503);
    struct Stream {
      size_t next = 0;
      std::string last_state;
      std::chrono::steady_clock::time_point last_write = std::chrono::steady_clock::now();
    };
    auto st = std::make_shared<Stream>();
    st->next = SinceParam(req);
    res.set_header("Cache-Control", "no-store");
    const std::string addr = req.remote_addr;
    const int port = req.remote_port;
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, st](size_t, httplib::DataSink& sink) {
          if (stopping_ || service_.shutting_down()) {
            sink.done();
            return true;
          }
          // Nothing here may throw into cpp-httplib's writer: the stream ends instead.
          try {
            std::string out = EventsSince(service_, st->next, st->last_state);
            const auto now = std::chrono::steady_clock::now();
            // A comment now and then, so that a client that went away is noticed (the write
            // fails) and its thread freed, even when nothing changes.
            if (out.empty() && now - st->last_write >= std::chrono::duration<double>(options_.heartbeat_s))
              out = ": heartbeat\n\n";
            if (!out.empty()) {
              if (!sink.write(out.data(), out.size())) return false;
              st->last_write = now;
            }
            if (sink.is_writable && !sink.is_writable()) return false;
          } catch (const std::exception& e) {
            Log("rig")->error("daemon: event stream ended: {}", e.what());
            return false;
          }
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
          return true;
        },
        [guard, addr, port](bool) {
          if (guard) guard->EndStream(addr, port);
        });
  }));
}

}  // namespace rig
