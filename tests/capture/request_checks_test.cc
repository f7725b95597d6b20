// The daemon's request checks as pure functions (capture/service/request_checks.h): each
// refusal and its status, and the requests that pass, on a policy like `rig daemon`'s default
// (127.0.0.1:7130, no Bearer token).
#include "capture/service/request_checks.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace rig {
namespace {

using ::testing::HasSubstr;

RequestPolicy Loopback() {
  RequestPolicy p;
  p.listen_host = "127.0.0.1";
  p.port = 7130;
  p.page_token = std::string(64, 'a');
  return p;
}

// A POST as `rig capture --daemon` sends it.
RequestFacts CliPost(const std::string& path = "/api/jobs") {
  RequestFacts r;
  r.method = "POST";
  r.path = path;
  r.host = "127.0.0.1:7130";
  r.content_type = "application/json";
  r.content_length = "2";
  return r;
}

int StatusOf(const RequestFacts& r, const RequestPolicy& p) {
  auto x = CheckRequest(r, p);
  return x ? x->status : 0;
}

TEST(RequestChecks, HostHeadersParseWithPortsAndBrackets) {
  auto h = ParseHostHeader("LocalHost:7130");
  ASSERT_TRUE(h);
  EXPECT_EQ(h->name, "localhost");
  EXPECT_EQ(h->port, 7130);
  h = ParseHostHeader("[::1]:80");
  ASSERT_TRUE(h);
  EXPECT_EQ(h->name, "::1");
  EXPECT_EQ(h->port, 80);
  h = ParseHostHeader("rig.lan");
  ASSERT_TRUE(h);
  EXPECT_EQ(h->port, -1);
  for (const char* bad : {"", ":80", "a:", "a:b", "a:99999", "a b", "[::1", "[::1]x", "[zz]:1",
                          "a:1:2", "a/b", "a\r\nX: y", "[]:1"})
    EXPECT_FALSE(ParseHostHeader(bad)) << bad;
}

TEST(RequestChecks, OnlyTheListeningAddressLoopbackNamesAndAllowedHostsPass) {
  RequestPolicy p = Loopback();
  RequestFacts r;
  r.method = "GET";
  r.path = "/api/status";
  for (const char* ok : {"127.0.0.1:7130", "localhost:7130", "127.9.9.9:7130", "[::1]:7130"}) {
    r.host = ok;
    EXPECT_EQ(StatusOf(r, p), 0) << ok;
  }
  for (const char* no : {"evil.example:7130", "127.0.0.1:7131", "127.0.0.1", "10.0.0.1:7130",
                         "localhost.evil.example:7130"}) {
    r.host = no;
    auto x = CheckRequest(r, p);
    ASSERT_TRUE(x) << no;
    EXPECT_EQ(x->status, 421) << no;
    EXPECT_THAT(x->error, HasSubstr(std::string("'") + no + "'"));
  }
  r.host.reset();
  EXPECT_EQ(StatusOf(r, p), 421);
  r.host = "bad host";
  EXPECT_EQ(StatusOf(r, p), 400);
  // --allowed-host NAME (any port) and NAME:PORT (that port only).
  p.allowed_hosts = {"rig.lan", "proxy.example:8443"};
  r.host = "RIG.lan:9";
  EXPECT_EQ(StatusOf(r, p), 0);
  r.host = "proxy.example:8443";
  EXPECT_EQ(StatusOf(r, p), 0);
  r.host = "proxy.example";
  EXPECT_EQ(StatusOf(r, p), 421);
  // Listening on every address: address literals pass, names do not.
  p = Loopback();
  p.listen_host = "0.0.0.0";
  r.host = "192.168.1.20:7130";
  EXPECT_EQ(StatusOf(r, p), 0);
  r.host = "attacker.example:7130";
  EXPECT_EQ(StatusOf(r, p), 421);
}

TEST(RequestChecks, StateChangesNeedJsonNoForeignOriginAndThePageTokenFromABrowser) {
  const RequestPolicy p = Loopback();
  RequestFacts r = CliPost();
  EXPECT_EQ(StatusOf(r, p), 0);  // the command-line client
  for (const char* simple : {"text/plain", "application/x-www-form-urlencoded",
                             "multipart/form-data; boundary=x", "application/jsonx", "json"}) {
    r.content_type = simple;
    auto x = CheckRequest(r, p);
    ASSERT_TRUE(x) << simple;
    EXPECT_EQ(x->status, 415) << simple;
    EXPECT_THAT(x->error, HasSubstr("needs Content-Type application/json"));
  }
  r.content_type.reset();
  EXPECT_EQ(StatusOf(r, p), 415);
  r.content_type = "Application/JSON; charset=utf-8";
  EXPECT_EQ(StatusOf(r, p), 0);

  for (const char* foreign : {"http://evil.example", "null", "http://127.0.0.1:7131", "file://",
                              "http://127.0.0.1:7130.evil.example", "ftp://127.0.0.1:7130"}) {
    r.origin = foreign;
    auto x = CheckRequest(r, p);
    ASSERT_TRUE(x) << foreign;
    EXPECT_EQ(x->status, 403) << foreign;
    EXPECT_THAT(x->error, HasSubstr("Origin"));
  }
  r.origin = "http://127.0.0.1:7130";  // the page's own origin, but no token
  auto x = CheckRequest(r, p);
  ASSERT_TRUE(x);
  EXPECT_EQ(x->status, 403);
  EXPECT_THAT(x->error, HasSubstr("X-Rig-Page-Token"));
  r.page_token = std::string(64, 'b');
  EXPECT_EQ(StatusOf(r, p), 403);
  r.page_token = std::string(63, 'a');
  EXPECT_EQ(StatusOf(r, p), 403);
  r.page_token = p.page_token;
  EXPECT_EQ(StatusOf(r, p), 0);
  r.sec_fetch_site = "cross-site";
  EXPECT_EQ(StatusOf(r, p), 403);
  r.sec_fetch_site = "same-site";  // another port of the same host
  EXPECT_EQ(StatusOf(r, p), 403);
  r.sec_fetch_site = "same-origin";
  EXPECT_EQ(StatusOf(r, p), 0);
  // No Origin but Sec-Fetch-Mode: a browser all the same.
  RequestFacts b = CliPost();
  b.sec_fetch_mode = "no-cors";
  EXPECT_EQ(StatusOf(b, p), 403);
  // A page token on a daemon without one (empty) never matches.
  RequestPolicy none = p;
  none.page_token.clear();
  r.page_token = "";
  EXPECT_EQ(StatusOf(r, none), 403);
  // GET, HEAD and OPTIONS change nothing: no content type asked.
  RequestFacts g;
  g.method = "GET";
  g.path = "/api/jobs";
  g.host = "127.0.0.1:7130";
  g.origin = "http://evil.example";  // a read; the browser does not let that page see the answer
  EXPECT_EQ(StatusOf(g, p), 0);
}

TEST(RequestChecks, BodiesAreBoundedAndStateChangesStateTheirLength) {
  const RequestPolicy p = Loopback();
  RequestFacts r = CliPost();
  r.content_length = std::to_string(kMaxBodyBytes);
  EXPECT_EQ(StatusOf(r, p), 0);
  r.content_length = std::to_string(kMaxBodyBytes + 1);
  auto x = CheckRequest(r, p);
  ASSERT_TRUE(x);
  EXPECT_EQ(x->status, 413);
  EXPECT_THAT(x->error, HasSubstr("1048577 bytes"));
  r.content_length = "536870912";
  EXPECT_EQ(StatusOf(r, p), 413);
  for (const char* bad : {"", "-1", "1e9", " 5", "99999999999999999999", "0x10"}) {
    r.content_length = bad;
    EXPECT_EQ(StatusOf(r, p), 400) << bad;
  }
  r.content_length.reset();
  EXPECT_EQ(StatusOf(r, p), 411);
  r.content_length = "2";
  r.transfer_encoding = "chunked";
  EXPECT_EQ(StatusOf(r, p), 411);
  RequestFacts g;
  g.method = "GET";
  g.path = "/api/status";
  g.host = "127.0.0.1:7130";
  EXPECT_EQ(StatusOf(g, p), 0);  // no length needed
  g.content_length = "2000000";
  EXPECT_EQ(StatusOf(g, p), 413);  // but a GET's body is bounded too
}

TEST(RequestChecks, TheBearerTokenGuardsTheApiAndStandsInForThePageToken) {
  RequestPolicy p = Loopback();
  p.bearer_token = "s3cret";
  RequestFacts r = CliPost();
  EXPECT_EQ(StatusOf(r, p), 401);
  r.authorization = "Bearer s3cre";
  EXPECT_EQ(StatusOf(r, p), 401);
  r.authorization = "Bearer s3cret";
  EXPECT_EQ(StatusOf(r, p), 0);
  r.origin = "http://127.0.0.1:7130";  // from the page, with the Bearer token of its #fragment
  EXPECT_EQ(StatusOf(r, p), 0);
  RequestFacts page;
  page.method = "GET";
  page.path = "/";
  page.host = "127.0.0.1:7130";
  EXPECT_EQ(StatusOf(page, p), 0);  // the page holds no data
  EXPECT_TRUE(SameSecret("abc", "abc"));
  EXPECT_FALSE(SameSecret("abd", "abc"));
  EXPECT_FALSE(SameSecret("", ""));
  const std::string t = RandomToken();
  EXPECT_EQ(t.size(), 64u);
  EXPECT_EQ(t.find_first_not_of("0123456789abcdef"), std::string::npos);
  EXPECT_NE(t, RandomToken());
}

TEST(RequestChecks, ClientPathsWithNulOrControlCharactersAreRefused) {
  EXPECT_EQ(ClientPathProblem("/home/u/.local/share/rig/sessions/S 1"), "");
  EXPECT_THAT(ClientPathProblem(std::string("/a\0b", 4)), HasSubstr("a NUL byte at offset 2"));
  EXPECT_THAT(ClientPathProblem("/a\nb"), HasSubstr("control character (0x0a) at offset 2"));
  EXPECT_THAT(ClientPathProblem("/a\x7f"), HasSubstr("0x7f"));
  EXPECT_THAT(ClientPathProblem(std::string(4097, 'a')), HasSubstr("4097 bytes"));
  EXPECT_TRUE(IsStateChanging("POST"));
  EXPECT_TRUE(IsStateChanging("DELETE"));
  EXPECT_FALSE(IsStateChanging("GET"));
  EXPECT_FALSE(IsStateChanging("OPTIONS"));
}

}  // namespace
}  // namespace rig
