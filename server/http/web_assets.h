// The dashboard's files (server/http/web/), compiled into vsurg-server at build time
// (cmake/embed_files.cmake), so the server needs no folder, no CDN and no internet at run time.
#pragma once

#include <optional>
#include <string_view>

namespace vsurg::server::http {

struct Asset {
  std::string_view type;  // Content-Type
  std::string_view body;
};

// "/index.html" (the page shell), "/app.js", "/style.css", …; nullopt when there is no such file.
std::optional<Asset> FindAsset(std::string_view path);

}  // namespace vsurg::server::http
