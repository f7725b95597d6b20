// The status page served at "/": capture/service/page/ (embedded at build time), index.html
// with this process's page token filled in.
#include "capture/service/http_server.h"

namespace rig {

std::string StatusPageHtml(const std::string& page_token) {
  std::string html;
  for (const auto& [name, content] : StatusPageAssets())
    if (name == "index.html") html = content;
  const std::string mark = "{{RIG_PAGE_TOKEN}}";
  if (size_t at = html.find(mark); at != std::string::npos) html.replace(at, mark.size(), page_token);
  return html;
}

}  // namespace rig
