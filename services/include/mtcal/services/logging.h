#pragma once
// Where mtcal's log goes: stderr, always, so that a front end's stdout carries only its
// results (one JSON document with --json, a benchmark's report).

#include <string>

namespace mtcal::services {

/// Sends the log (spdlog's default logger) to stderr at `level`: off, error, warn, info, debug.
/// @throws InputError for another level
void logToStderr(const std::string& level);

}  // namespace mtcal::services
