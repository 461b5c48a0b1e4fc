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

/// `text` (a plan's, a phase's or a hole's name) as it can stand inside a comment: a comment
/// ends at its first ')' and may hold no '(' (RS274/NGC, NIST IR 6556, 3.3.4; DIN 66025), so
/// parentheses become brackets, and a line end a space.
std::string gcodeCommentText(std::string text);

/// The comment line (with its line end) a program's header says its dwells' unit in: an "iso"
/// G4 P read as milliseconds by a Fanuc-style control would dwell a thousandth of the time.
std::string gcodeDwellComment(const std::string& dialect);

}  // namespace mtcal::acquisition
