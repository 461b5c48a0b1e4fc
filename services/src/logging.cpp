#include "mtcal/services/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "mtcal/error.h"

namespace mtcal::services {

void logToStderr(const std::string& level) {
  const auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    throw InputError("log level '" + level + "': off, error, warn, info or debug");
  }
  auto logger = spdlog::get("mtcal");
  if (!logger) logger = spdlog::stderr_color_mt("mtcal");
  spdlog::set_default_logger(logger);
  spdlog::set_level(parsed);
}

}  // namespace mtcal::services
