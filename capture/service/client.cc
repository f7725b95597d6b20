// The daemon's client side.
#include "capture/service/client.h"

#include <httplib.h>

#include "capture/service/http_server.h"

namespace rig {
namespace {

Result<nlohmann::json> Answer(const DaemonAddress& a, const std::string& path,
                              const httplib::Result& res) {
  const std::string where = a.Url() + path.substr(1);
  if (!res)
    return MakeError(ErrorCode::kNotFound, where, "no daemon answers ({}); is 'rig daemon' running?",
                     httplib::to_string(res.error()));
  auto j = nlohmann::json::parse(res->body, nullptr, /*allow_exceptions=*/false);
  if (res->status >= 200 && res->status < 300) {
    if (j.is_discarded())
      return MakeError(ErrorCode::kIo, where, "the answer is not JSON (is this a rig daemon?)");
    return j;
  }
  std::string msg = !j.is_discarded() && j.is_object() && j.contains("error") && j["error"].is_string()
                        ? j["error"].get<std::string>()
                        : res->body;
  ErrorCode code = ErrorCode::kIo;
  if (res->status == 400 || res->status == 401) code = ErrorCode::kInvalidInput;
  if (res->status == 404) code = ErrorCode::kNotFound;
  if (res->status == 409) code = ErrorCode::kBusy;
  return MakeError(code, where, "HTTP {}: {}", res->status, msg);
}

}  // namespace

std::string DaemonAddress::Url() const {
  const bool v6 = host.find(':') != std::string::npos;
  return fmt::format("http://{}{}{}:{}/", v6 ? "[" : "", host, v6 ? "]" : "", port);
}

Result<DaemonAddress> ParseDaemonUrl(const std::string& url) {
  std::string rest = url;
  if (rest.rfind("https://", 0) == 0)
    return MakeError(ErrorCode::kInvalidInput, url, "the daemon serves plain HTTP; use http://");
  if (rest.rfind("http://", 0) == 0) rest = rest.substr(7);
  while (!rest.empty() && rest.back() == '/') rest.pop_back();
  if (rest.find('/') != std::string::npos)
    return MakeError(ErrorCode::kInvalidInput, url, "expected http://HOST:PORT");
  if (rest.find(':') == std::string::npos && rest.find_first_not_of("0123456789") != std::string::npos)
    rest += ":" + std::to_string(kDefaultDaemonPort);
  auto hp = ParseListenAddress(rest);
  if (!hp.ok()) return MakeError(ErrorCode::kInvalidInput, url, "expected http://HOST:PORT");
  DaemonAddress a;
  a.host = hp->first;
  a.port = hp->second;
  return a;
}

DaemonClient::DaemonClient(DaemonAddress address, double timeout_s)
    : address_(std::move(address)), timeout_s_(timeout_s) {}

namespace {
httplib::Client MakeClient(const DaemonAddress& a, double timeout_s) {
  httplib::Client c(a.host, a.port);
  const auto t = std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000));
  c.set_connection_timeout(t);
  c.set_read_timeout(t);
  c.set_write_timeout(t);
  if (!a.token.empty()) c.set_bearer_token_auth(a.token);
  return c;
}
}  // namespace

Result<nlohmann::json> DaemonClient::Get(const std::string& path) {
  httplib::Client c = MakeClient(address_, timeout_s_);
  return Answer(address_, path, c.Get(path));
}

Result<nlohmann::json> DaemonClient::Post(const std::string& path, const nlohmann::json& body) {
  httplib::Client c = MakeClient(address_, timeout_s_);
  return Answer(address_, path, c.Post(path, body.dump(), "application/json"));
}

}  // namespace rig
