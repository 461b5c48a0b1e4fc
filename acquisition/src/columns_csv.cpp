#include "mtcal/acquisition/columns_csv.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>

#include "csv.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {

std::map<std::string, std::vector<double>> readColumnsCsv(std::istream& in, const std::string& source,
                                                          const std::vector<std::string>& required,
                                                          const std::vector<std::string>& optional) {
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  while (header.empty() && std::getline(in, line)) {
    ++line_no;
    const std::string t = csv::trim(line);
    if (!t.empty() && t[0] != '#') header = csv::split(t);
  }
  std::map<std::string, std::size_t> index;
  for (std::size_t i = 0; i < header.size(); ++i) index[header[i]] = i;
  std::map<std::string, std::vector<double>> out;
  for (const auto& name : required) {
    if (!index.count(name)) {
      throw InputError(fmt::format("{}:{}: missing column '{}' (need {})", source, line_no, name, fmt::join(required, ", ")));
    }
    out[name];
  }
  for (const auto& name : optional) {
    if (index.count(name)) out[name];
  }
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = csv::trim(line);
    if (t.empty() || t[0] == '#') continue;
    const auto cells = csv::split(t);
    if (cells.size() != header.size()) {
      throw InputError(fmt::format("{}:{}: {} fields, the header has {}", source, line_no, cells.size(), header.size()));
    }
    for (auto& [name, values] : out) {
      const std::string& text = cells[index.at(name)];
      double v = 0.0;
      const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
      if (text.empty() || ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(v)) {
        throw InputError(fmt::format("{}:{}: column '{}': '{}' is not a number", source, line_no, name, text));
      }
      values.push_back(v);
    }
  }
  if (!out.empty() && out.begin()->second.empty()) throw InputError(source + ": no data rows");
  return out;
}

}  // namespace mtcal::acquisition
