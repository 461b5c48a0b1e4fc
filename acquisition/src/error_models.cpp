#include "mtcal/acquisition/error_models.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  return std::string(s.substr(b, s.find_last_not_of(" \t\r") - b + 1));
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::size_t start = 0;
  for (;;) {
    const auto comma = line.find(',', start);
    cells.push_back(trim(std::string_view(line).substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) return cells;
    start = comma + 1;
  }
}

}  // namespace

std::vector<processing::ErrorCurveData> parseErrorCurvesCsv(std::istream& in, const std::string& source) {
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  while (header.empty() && std::getline(in, line)) {
    ++line_no;
    const std::string t = trim(line);
    if (!t.empty() && t[0] != '#') header = split(t);
  }
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  for (const char* required : {"error", "position_mm", "value"}) {
    if (!col.count(required)) {
      throw InputError(fmt::format("{}:{}: missing column '{}' (need error, position_mm, value; optional s)", source,
                                   line_no, required));
    }
  }
  // error -> position (NaN for a constant) -> values and given s
  struct Node {
    std::vector<double> values;
    std::optional<double> s;
    std::optional<int> n;  ///< repeats behind a given s
  };
  std::map<std::string, std::map<double, Node>> curves;
  const double kConstant = -std::numeric_limits<double>::infinity();
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const auto cells = split(t);
    if (cells.size() != header.size()) {
      throw InputError(fmt::format("{}:{}: {} fields, the header has {}", source, line_no, cells.size(), header.size()));
    }
    auto number = [&](const char* name) -> std::optional<double> {
      const std::string& text = cells[col.at(name)];
      if (text.empty()) return std::nullopt;
      double v = 0.0;
      auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
      if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(v)) {
        throw InputError(fmt::format("{}:{}: column '{}': '{}' is not a number", source, line_no, name, text));
      }
      return v;
    };
    const std::string error = cells[col.at("error")];
    if (error.empty()) throw InputError(fmt::format("{}:{}: column 'error': empty", source, line_no));
    const auto value = number("value");
    if (!value) throw InputError(fmt::format("{}:{}: column 'value': missing", source, line_no));
    const auto position = number("position_mm");
    Node& node = curves[error][position.value_or(kConstant)];
    node.values.push_back(*value);
    if (col.count("s")) {
      if (auto s = number("s")) {
        if (*s < 0.0) throw InputError(fmt::format("{}:{}: column 's': must not be negative", source, line_no));
        node.s = s;
      }
    }
    if (col.count("n")) {
      if (auto n = number("n")) {
        if (*n < 1 || *n != std::floor(*n)) throw InputError(fmt::format("{}:{}: column 'n': a whole number >= 1", source, line_no));
        node.n = static_cast<int>(*n);
      }
    }
  }
  std::vector<processing::ErrorCurveData> out;
  for (const auto& [error, nodes] : curves) {
    processing::ErrorCurveData d;
    d.name = error;
    if (nodes.count(kConstant) && nodes.size() > 1) {
      throw InputError(fmt::format("{}: error {} has rows with and without a position", source, error));
    }
    for (const auto& [position, node] : nodes) {
      const auto n = static_cast<int>(node.values.size());
      double mean = 0.0;
      for (double v : node.values) mean += v;
      mean /= n;
      std::optional<double> s = node.s;
      if (!s && n >= 2) {
        double ss = 0.0;
        for (double v : node.values) ss += (v - mean) * (v - mean);
        s = std::sqrt(ss / (n - 1));
      }
      if (position != kConstant) d.position_mm.push_back(position);
      d.mean.push_back(mean);
      d.s.push_back(s);
      // A given s without its n counts as estimated from 2 repeats: the fewest degrees of
      // freedom, so the t-corrected bands are never narrower than the data justify.
      d.repeats.push_back(node.s ? node.n.value_or(std::max(n, 2)) : n);
    }
    out.push_back(std::move(d));
  }
  if (out.empty()) throw InputError(source + ": no data rows");
  return out;
}

storage::Id saveModel(storage::Store& store, const processing::ErrorModel& model, const ModelProvenance& provenance) {
  storage::ModelRecord record;
  record.name = provenance.name;
  record.method = provenance.method;
  record.provenance_json = provenance.provenance_json;
  record.machine_json = provenance.machine_json;
  record.software_version = provenance.software_version;
  for (const auto& f : model.functions()) record.error_functions.emplace_back(f.name(), f.toJson().dump());
  return store.addModel(record);
}

processing::ErrorModel loadModel(storage::Store& store, storage::Id model_id) {
  const auto record = store.model(model_id);
  const auto source = fmt::format("model {}", model_id);
  auto machine = processing::MultibodyModel::fromJson(nlohmann::json::parse(record.machine_json), source);
  std::vector<processing::ErrorFunction> functions;
  for (const auto& [name, json] : record.error_functions) {
    functions.push_back(processing::ErrorFunction::fromJson(name, nlohmann::json::parse(json)));
  }
  return processing::ErrorModel(std::move(machine), std::move(functions));
}

}  // namespace mtcal::acquisition
