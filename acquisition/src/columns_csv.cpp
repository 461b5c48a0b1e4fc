#include "mtcal/acquisition/columns_csv.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>

#include "csv.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {

ColumnTable readColumnTable(std::istream& in, const std::string& source, const std::vector<std::string>& required,
                            const std::vector<std::string>& optional, const std::vector<std::string>& text) {
  csv::Reader reader(in, source);
  const std::vector<std::string> header = reader.next().value_or(std::vector<std::string>{});
  const int header_line = reader.line();
  std::map<std::string, std::size_t> index;
  for (std::size_t i = 0; i < header.size(); ++i) index[header[i]] = i;
  ColumnTable table;
  auto& out = table.numbers;
  for (const auto& name : required) {
    if (!index.count(name)) {
      throw InputError(
          fmt::format("{}:{}: missing column '{}' (need {})", source, header_line, name, fmt::join(required, ", ")));
    }
    out[name];
  }
  for (const auto& name : text) {
    if (!index.count(name)) {
      throw InputError(
          fmt::format("{}:{}: missing column '{}' (need {})", source, header_line, name, fmt::join(text, ", ")));
    }
    table.texts[name];
  }
  for (const auto& name : optional) {
    if (index.count(name)) out[name];
  }
  while (const auto row = reader.row(header)) {
    const auto& cells = *row;
    const int line_no = reader.line();
    for (auto& [name, values] : out) {
      const std::string& text = cells[index.at(name)];
      const auto v = csv::number(text);
      if (!v) throw InputError(fmt::format("{}:{}: column '{}': '{}' is not a number", source, line_no, name, text));
      values.push_back(*v);
    }
    for (auto& [name, values] : table.texts) {
      const std::string& cell = cells[index.at(name)];
      if (cell.empty()) throw InputError(fmt::format("{}:{}: column '{}': empty", source, line_no, name));
      values.push_back(cell);
    }
    table.lines.push_back(line_no);
  }
  if (table.lines.empty()) throw InputError(source + ": no data rows");
  return table;
}

std::map<std::string, std::vector<double>> readColumnsCsv(std::istream& in, const std::string& source,
                                                          const std::vector<std::string>& required,
                                                          const std::vector<std::string>& optional) {
  return readColumnTable(in, source, required, optional, {}).numbers;
}

}  // namespace mtcal::acquisition
