#pragma once
// What every part program mtcal writes shares: the dialect's words. A dialect states its
// units; a dwell is in seconds in both ("iso": G4 P<s>, as LinuxCNC and Siemens' ISO mode read
// it; "fanuc": G04 X<s>, Fanuc's X-form, which is seconds whatever the increment system).

#include <string>

namespace mtcal::acquisition {

/// The dialects part programs are written in.
inline constexpr const char* kGcodeDialects[] = {"iso", "fanuc"};

/// A dwell of `seconds` in `dialect`, without a line end. @throws InputError for another dialect
std::string gcodeDwell(const std::string& dialect, double seconds);

}  // namespace mtcal::acquisition
