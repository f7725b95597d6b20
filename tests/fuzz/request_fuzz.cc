// Fuzzes the daemon's request checks (capture/service/request_checks.cc): any bytes as a
// request head ("METHOD PATH" then "Name: value" lines), checked against a loopback policy
// and one listening everywhere with a Bearer token and an --allowed-host. A refusal is one of
// the statuses the checks give, with a printable message; a request that passes a
// state-changing check is JSON and names an accepted Host; Host parsing is stable.
#include <cstdint>
#include <cstdio>
#include <string>

#include "capture/service/request_checks.h"
#include "tests/fuzz/fuzz_support.h"

namespace {

[[noreturn]] void Fail(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz: %s: %s\n", what, detail.c_str());
  __builtin_trap();
}

rig::RequestFacts Parse(std::string_view text) {
  rig::RequestFacts r;
  size_t pos = 0, line_no = 0;
  while (pos <= text.size()) {
    size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    std::string line(text.substr(pos, nl - pos));
    pos = nl + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line_no++ == 0) {
      const size_t sp = line.find(' ');
      r.method = line.substr(0, sp);
      r.path = sp == std::string::npos ? "/" : line.substr(sp + 1);
      continue;
    }
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string name = line.substr(0, colon), value = line.substr(colon + 1);
    while (!value.empty() && value.front() == ' ') value.erase(value.begin());
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (name == "host") r.host = value;
    else if (name == "origin") r.origin = value;
    else if (name == "content-type") r.content_type = value;
    else if (name == "content-length") r.content_length = value;
    else if (name == "transfer-encoding") r.transfer_encoding = value;
    else if (name == "sec-fetch-site") r.sec_fetch_site = value;
    else if (name == "sec-fetch-mode") r.sec_fetch_mode = value;
    else if (name == "authorization") r.authorization = value;
    else if (name == "x-rig-page-token") r.page_token = value;
  }
  return r;
}

void Check(const rig::RequestFacts& r, const rig::RequestPolicy& p) {
  auto refusal = rig::CheckRequest(r, p);
  if (refusal) {
    const int s = refusal->status;
    if (s != 400 && s != 401 && s != 403 && s != 411 && s != 413 && s != 415 && s != 421)
      Fail("unexpected status", std::to_string(s));
    if (refusal->error.empty()) Fail("empty message", std::to_string(s));
    for (char c : refusal->error)
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) Fail("unprintable message", refusal->error);
    return;
  }
  if (!r.host || !rig::ParseHostHeader(*r.host)) Fail("passed without a valid Host", r.host.value_or("none"));
  if (rig::IsStateChanging(r.method) && (!r.content_type || !rig::IsJsonContentType(*r.content_type)))
    Fail("a state change passed without JSON", r.content_type.value_or("none"));
  if (!p.bearer_token.empty() && r.path.rfind("/api/", 0) == 0 && !r.authorization)
    Fail("an API request passed without the Bearer token", r.path);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const rig::RequestFacts r = Parse(rig::fuzz::AsText(data, size));
  rig::RequestPolicy loopback;
  loopback.listen_host = "127.0.0.1";
  loopback.port = 7130;
  loopback.page_token = std::string(64, 'a');
  Check(r, loopback);
  rig::RequestPolicy remote = loopback;
  remote.listen_host = "0.0.0.0";
  remote.bearer_token = "s3cret";
  remote.allowed_hosts = {"rig.lan", "proxy.example:8443"};
  Check(r, remote);
  if (r.host) {
    if (auto h = rig::ParseHostHeader(*r.host)) {
      const bool v6 = h->name.find(':') != std::string::npos;
      std::string again = (v6 ? "[" + h->name + "]" : h->name) + (h->port >= 0 ? ":" + std::to_string(h->port) : "");
      auto h2 = rig::ParseHostHeader(again);
      if (!h2 || h2->name != h->name || h2->port != h->port) Fail("Host parsing is not stable", *r.host);
    }
  }
  (void)rig::ClientPathProblem(r.path);
  return 0;
}
