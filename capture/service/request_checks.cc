// The checks every request passes before its handler (request_checks.h).
#include "capture/service/request_checks.h"

#include <arpa/inet.h>
#include <sys/random.h>

#include <algorithm>
#include <cctype>

#include <fmt/format.h>

namespace rig {
namespace {

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// A header's value quoted for a message: at most 80 printable characters.
std::string Quoted(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 80)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (s.size() > 80) out += "...";
  return "'" + out + "'";
}

// A method for a message: printable, at most 16 characters.
std::string Method(std::string_view m) {
  std::string out;
  for (char c : m.substr(0, 16)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  return out;
}

bool IsLoopbackName(const std::string& name) {
  if (name == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, name.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, name.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

bool IsIpLiteral(const std::string& name) {
  in_addr v4{};
  in6_addr v6{};
  return inet_pton(AF_INET, name.c_str(), &v4) == 1 || inet_pton(AF_INET6, name.c_str(), &v6) == 1;
}

bool IsWildcard(const std::string& host) { return host == "0.0.0.0" || host == "::" || host.empty(); }

// An --allowed-host entry (NAME or NAME:PORT) that admits `h`.
bool Allowed(const HostPort& h, const std::vector<std::string>& allowed) {
  for (const std::string& a : allowed) {
    auto entry = ParseHostHeader(a);
    if (!entry || entry->name != h.name) continue;
    if (entry->port < 0 || entry->port == h.port) return true;
  }
  return false;
}

bool HostAccepted(const HostPort& h, const RequestPolicy& p) {
  if (Allowed(h, p.allowed_hosts)) return true;
  const int port = h.port < 0 ? 80 : h.port;
  if (port != p.port) return false;
  std::string listen = Lower(p.listen_host);
  if (listen.size() > 2 && listen.front() == '[' && listen.back() == ']')
    listen = listen.substr(1, listen.size() - 2);
  if (IsLoopbackName(h.name) || h.name == listen) return true;
  // Listening on every address: a client that reached it by an address literal is not a
  // rebinding page (that one names its own host); names need --allowed-host.
  return IsWildcard(listen) && IsIpLiteral(h.name);
}

Refusal Refuse(int status, std::string error) { return Refusal{status, std::move(error)}; }

}  // namespace

std::optional<HostPort> ParseHostHeader(std::string_view text) {
  if (text.empty() || text.size() > 255) return std::nullopt;
  HostPort out;
  std::string_view name = text, port;
  if (text.front() == '[') {
    size_t close = text.find(']');
    if (close == std::string_view::npos) return std::nullopt;
    name = text.substr(1, close - 1);
    std::string_view rest = text.substr(close + 1);
    if (!rest.empty()) {
      if (rest.front() != ':') return std::nullopt;
      port = rest.substr(1);
      if (port.empty()) return std::nullopt;
    }
    if (name.empty() || name.find_first_not_of("0123456789abcdefABCDEF:.") != std::string_view::npos)
      return std::nullopt;
  } else {
    size_t colon = text.find(':');
    if (colon != std::string_view::npos) {
      name = text.substr(0, colon);
      port = text.substr(colon + 1);
      if (port.empty()) return std::nullopt;
    }
    if (name.empty() ||
        name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-_") !=
            std::string_view::npos)
      return std::nullopt;
  }
  if (!port.empty()) {
    if (port.size() > 5 || port.find_first_not_of("0123456789") != std::string_view::npos)
      return std::nullopt;
    out.port = std::stoi(std::string(port));
    if (out.port > 65535) return std::nullopt;
  }
  out.name = Lower(name);
  return out;
}

bool IsStateChanging(std::string_view method) {
  return method != "GET" && method != "HEAD" && method != "OPTIONS";
}

bool IsJsonContentType(std::string_view content_type) {
  std::string t = Lower(content_type.substr(0, content_type.find(';')));
  while (!t.empty() && (t.back() == ' ' || t.back() == '\t')) t.pop_back();
  while (!t.empty() && (t.front() == ' ' || t.front() == '\t')) t.erase(t.begin());
  return t == "application/json";
}

bool SameSecret(std::string_view given, std::string_view expected) {
  if (expected.empty() || given.size() != expected.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < given.size(); ++i)
    diff |= static_cast<unsigned char>(given[i] ^ expected[i]);
  return diff == 0;
}

std::string RandomToken() {
  unsigned char bytes[32];
  size_t got = 0;
  while (got < sizeof bytes) {
    ssize_t n = getrandom(bytes + got, sizeof bytes - got, 0);
    if (n > 0) got += static_cast<size_t>(n);
  }
  std::string out;
  for (unsigned char b : bytes) out += fmt::format("{:02x}", b);
  return out;
}

std::optional<Refusal> CheckHost(const RequestFacts& r, const RequestPolicy& p) {
  if (!r.host)
    return Refuse(421, "the request has no Host header (HTTP/1.1 requires one)");
  auto h = ParseHostHeader(*r.host);
  if (!h) return Refuse(400, fmt::format("malformed Host header {}", Quoted(*r.host)));
  if (HostAccepted(*h, p)) return std::nullopt;
  return Refuse(421, fmt::format("Host header {} is not this daemon's address ({}:{}, a loopback "
                                 "name, or an --allowed-host): refused, as a DNS-rebinding page "
                                 "would be",
                                 Quoted(*r.host), p.listen_host, p.port));
}

std::optional<Refusal> CheckLength(const RequestFacts& r) {
  if (r.transfer_encoding && Lower(*r.transfer_encoding) != "identity")
    return Refuse(411, fmt::format("Transfer-Encoding {} is not accepted: send the body with a "
                                   "Content-Length (at most {} bytes)",
                                   Quoted(*r.transfer_encoding), kMaxBodyBytes));
  if (r.content_length) {
    const std::string& v = *r.content_length;
    if (v.empty() || v.size() > 19 || v.find_first_not_of("0123456789") != std::string::npos)
      return Refuse(400, fmt::format("malformed Content-Length {}", Quoted(v)));
    const unsigned long long n = std::stoull(v);
    if (n > kMaxBodyBytes)
      return Refuse(413, fmt::format("a body of {} bytes (Content-Length): at most {} bytes", n,
                                     kMaxBodyBytes));
  } else if (IsStateChanging(r.method)) {
    return Refuse(411, fmt::format("{} {} needs a Content-Length header", Method(r.method),
                                   Quoted(r.path)));
  }
  return std::nullopt;
}

std::optional<Refusal> CheckBearer(const RequestFacts& r, const RequestPolicy& p) {
  if (p.bearer_token.empty() || r.path.rfind("/api/", 0) != 0) return std::nullopt;
  const std::string prefix = "Bearer ";
  if (r.authorization && r.authorization->rfind(prefix, 0) == 0 &&
      SameSecret(std::string_view(*r.authorization).substr(prefix.size()), p.bearer_token))
    return std::nullopt;
  return Refuse(401, "this daemon needs 'Authorization: Bearer TOKEN' (its --token-file)");
}

std::optional<Refusal> CheckStateChange(const RequestFacts& r, const RequestPolicy& p) {
  if (!IsStateChanging(r.method)) return std::nullopt;
  if (r.sec_fetch_site && (*r.sec_fetch_site == "cross-site" || *r.sec_fetch_site == "same-site"))
    return Refuse(403, fmt::format("Sec-Fetch-Site {}: {} {} is refused from another site's page",
                                   Quoted(*r.sec_fetch_site), Method(r.method), Quoted(r.path)));
  if (r.origin) {
    bool same = false;
    for (const char* scheme : {"http://", "https://"}) {
      if (r.origin->rfind(scheme, 0) != 0) continue;
      const std::string rest = r.origin->substr(std::string(scheme).size());
      auto o = ParseHostHeader(rest);
      same = o && ((r.host && Lower(rest) == Lower(*r.host)) || Allowed(*o, p.allowed_hosts));
    }
    if (!same)
      return Refuse(403, fmt::format("Origin {} is not this daemon's page ({}): {} {} refused",
                                     Quoted(*r.origin), r.host ? Quoted(*r.host) : "no Host",
                                     Method(r.method), Quoted(r.path)));
  }
  if (!r.content_type || !IsJsonContentType(*r.content_type))
    return Refuse(415, fmt::format("{} {} needs Content-Type application/json (got {})",
                                   Method(r.method), Quoted(r.path),
                                   r.content_type ? Quoted(*r.content_type) : "none"));
  const bool from_browser = r.origin || r.sec_fetch_site || r.sec_fetch_mode;
  if (!from_browser) return std::nullopt;
  const bool bearer = !p.bearer_token.empty() && r.authorization &&
                      SameSecret(*r.authorization, "Bearer " + p.bearer_token);
  if (bearer || (r.page_token && SameSecret(*r.page_token, p.page_token))) return std::nullopt;
  return Refuse(403, fmt::format("{} {} from a browser page needs the status page's {} header",
                                 Method(r.method), Quoted(r.path), kPageTokenHeader));
}

std::optional<Refusal> CheckRequest(const RequestFacts& r, const RequestPolicy& p) {
  if (auto x = CheckHost(r, p)) return x;
  if (auto x = CheckBearer(r, p)) return x;
  if (auto x = CheckLength(r)) return x;
  return CheckStateChange(r, p);
}

std::string ClientPathProblem(std::string_view path) {
  if (path.size() > 4096) return fmt::format("a path of {} bytes (at most 4096)", path.size());
  for (size_t i = 0; i < path.size(); ++i) {
    const auto c = static_cast<unsigned char>(path[i]);
    if (c == 0) return fmt::format("a NUL byte at offset {}", i);
    if (c < 0x20 || c == 0x7f) return fmt::format("a control character (0x{:02x}) at offset {}", c, i);
  }
  return "";
}

}  // namespace rig
