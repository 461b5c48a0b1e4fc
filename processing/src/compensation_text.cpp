#include "compensation_text.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "mtcal/error.h"

namespace mtcal::processing::format_text {

std::vector<std::string> linesOf(std::string_view text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    auto end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string line(text.substr(start, end - start));
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(std::move(line));
    start = end + 1;
  }
  return lines;
}

std::vector<double> leadingNumbers(const std::string& line, std::size_t count) {
  std::vector<double> numbers;
  const char* p = line.c_str();
  while (numbers.size() < count) {
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(p, &end);
    if (end == p || errno == ERANGE) break;
    numbers.push_back(v);
    p = end;
  }
  return numbers;
}

double numberOf(std::string_view text, const std::string& source, std::size_t line) {
  const std::string s(text);
  const auto first = s.find_first_not_of(" \t");
  const auto last = s.find_last_not_of(" \t");
  const std::string trimmed = first == std::string::npos ? "" : s.substr(first, last - first + 1);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(trimmed.c_str(), &end);
  if (trimmed.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
    throw InputError(fmt::format("{}: line {}: '{}' is not a number", source, line, trimmed));
  return v;
}

double equidistantStep(const CompensationTable& t, std::string_view controller) {
  const double step = t.position[1] - t.position[0];
  for (std::size_t i = 2; i < t.position.size(); ++i) {
    const double expected = t.position[0] + static_cast<double>(i) * step;
    if (std::abs(t.position[i] - expected) > 1e-6 * std::max(1.0, std::abs(step))) {
      throw InputError(
          fmt::format("{} takes entries at equal intervals: entry {} is at {:g}, not {:g}; give --interval", controller,
                      i + 1, t.position[i], expected));
    }
  }
  return step;
}

void requireOneTable(const CompensationTable& t, std::string_view controller, std::string_view instead) {
  if (t.bidirectional())
    throw InputError(fmt::format("{} applies one table to both directions: give --mean, or {}", controller, instead));
}

std::vector<double> gridPositions(double first, double step, std::size_t count) {
  std::vector<double> p;
  for (std::size_t i = 0; i < count; ++i) p.push_back(first + static_cast<double>(i) * step);
  return p;
}

CompensationTable withPeriodEnd(const CompensationTable& t) {
  if (!t.modulo) return t;
  CompensationTable closed = t;
  closed.position.push_back(t.position.front() + *t.modulo);
  closed.up_um.push_back(t.up_um.front());
  closed.down_um.push_back(t.down_um.front());
  return closed;
}

CompensationTable closedTable(CompensationTable t, bool modulo, const std::string& source) {
  if (modulo) {
    if (t.position.size() < 3) throw InputError(fmt::format("{}: a modulo table needs at least 3 entries", source));
    const double tolerance = 1e-6;
    if (std::abs(t.up_um.back() - t.up_um.front()) > tolerance ||
        std::abs(t.down_um.back() - t.down_um.front()) > tolerance) {
      throw InputError(
          fmt::format("{}: a modulo table's last value ({:g} um) must be its first one ({:g} um): the period starts "
                      "again there",
                      source, t.up_um.back(), t.up_um.front()));
    }
    t.modulo = t.position.back() - t.position.front();
    t.position.pop_back();
    t.up_um.pop_back();
    t.down_um.pop_back();
  }
  checkTable(t, source.c_str());
  return t;
}

}  // namespace mtcal::processing::format_text
