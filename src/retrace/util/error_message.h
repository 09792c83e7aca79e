#pragma once

// Error messages shown to a user: one line, whatever an input file put into them.

#include <string>

namespace retrace {

// An error message fit for one line of a terminal (or a Python exception): line breaks and tabs become spaces,
// other control characters and bytes that are not UTF-8 become '?', and an empty message says so.
std::string OneLineMessage(const std::string& message);

}  // namespace retrace
