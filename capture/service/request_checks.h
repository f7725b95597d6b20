// What the daemon refuses before a request reaches its handler (docs/daemon.md, "Threat
// model"): pure functions of the request's method, path and headers, so that they are tested
// and fuzzed without a socket.
//
//   Host        the address listened on, a loopback name or an --allowed-host, with the port
//               (421 otherwise: a DNS-rebinding page names its own host)
//   Bearer      when the daemon has a token, every /api/ request carries it (401)
//   Length      a body of at most kMaxBodyBytes (413); a state-changing request states its
//               length, and no request sends a chunked body (411)
//   POST etc.   Content-Type application/json (415: forms and text/plain need no preflight);
//               no foreign Origin, no Sec-Fetch-Site cross-site/same-site (403); from a
//               browser (Origin or Sec-Fetch-* present), the status page's token in
//               X-Rig-Page-Token or the Bearer token (403)
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rig {

inline constexpr size_t kMaxBodyBytes = size_t{1} << 20;
inline constexpr const char* kPageTokenHeader = "X-Rig-Page-Token";

// What the checks read of a request; a header absent is nullopt.
struct RequestFacts {
  std::string method;  // "GET", "POST", ...
  std::string path;
  std::optional<std::string> host, origin, content_type, content_length, transfer_encoding,
      sec_fetch_site, sec_fetch_mode, authorization, page_token;
};

// What the daemon accepts.
struct RequestPolicy {
  std::string listen_host;  // as given to --listen ("127.0.0.1", "::1", "0.0.0.0", a name)
  int port = 0;             // the bound port
  std::vector<std::string> allowed_hosts;  // --allowed-host: NAME (any port) or NAME:PORT
  std::string bearer_token;  // empty: none asked
  std::string page_token;    // the status page's, random per process; empty: page actions refused
};

struct Refusal {
  int status = 400;
  std::string error;  // the message of the JSON answer {"error": ...}
};

// "name[:port]" or "[v6][:port]" of a Host header, the name lower-cased, without brackets;
// port -1 when absent. nullopt when malformed (empty, bad port, stray characters).
struct HostPort {
  std::string name;
  int port = -1;
};
std::optional<HostPort> ParseHostHeader(std::string_view text);

// A method that changes state (anything but GET, HEAD, OPTIONS).
bool IsStateChanging(std::string_view method);
// "application/json" with optional parameters, any case.
bool IsJsonContentType(std::string_view content_type);
// Compares in time independent of where the strings differ; an empty `expected` never matches.
bool SameSecret(std::string_view given, std::string_view expected);
// 32 random bytes from the kernel, hex.
std::string RandomToken();

std::optional<Refusal> CheckHost(const RequestFacts& r, const RequestPolicy& p);
std::optional<Refusal> CheckBearer(const RequestFacts& r, const RequestPolicy& p);
std::optional<Refusal> CheckLength(const RequestFacts& r);
std::optional<Refusal> CheckStateChange(const RequestFacts& r, const RequestPolicy& p);
// Every check above, in that order: the first refusal.
std::optional<Refusal> CheckRequest(const RequestFacts& r, const RequestPolicy& p);

// A path given by a client (a session, a configuration): refused when it holds a NUL or a
// control character, or is longer than 4096 bytes. Empty string when acceptable, else why not.
std::string ClientPathProblem(std::string_view path);

}  // namespace rig
