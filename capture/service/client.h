// A client of `rig daemon` (rig status, rig capture/resume --daemon URL): JSON over HTTP.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "config/result.h"

namespace rig {

struct DaemonAddress {
  std::string host = "127.0.0.1";
  int port = 0;
  std::string token;  // sent as "Authorization: Bearer TOKEN" when set
  std::string Url() const;
};

// "http://HOST:PORT[/]", "HOST:PORT" or "PORT" (loopback). https is not served.
Result<DaemonAddress> ParseDaemonUrl(const std::string& url);

class DaemonClient {
 public:
  explicit DaemonClient(DaemonAddress address, double timeout_s = 10);
  // The JSON answer of GET/POST `path`; an HTTP error becomes an Error carrying the daemon's
  // message (400 kInvalidInput, 401 kInvalidInput, 404 kNotFound, 409 kBusy); no answer at
  // all is kNotFound ("no daemon at ...").
  Result<nlohmann::json> Get(const std::string& path);
  Result<nlohmann::json> Post(const std::string& path, const nlohmann::json& body);
  const DaemonAddress& address() const { return address_; }

 private:
  DaemonAddress address_;
  double timeout_s_;
};

}  // namespace rig
