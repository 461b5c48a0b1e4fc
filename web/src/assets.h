#pragma once
// The dashboard's pages, scripts and styles, compiled into the binary (web/assets).

#include <string_view>
#include <vector>

namespace mtcal::web {

struct Asset {
  std::string_view path;  ///< as requested: "/index.html"
  std::string_view media_type;
  std::string_view content;
};

/// Every asset; a request names one exactly or gets 404 (no path reaches the file system).
const std::vector<Asset>& assets();

}  // namespace mtcal::web
