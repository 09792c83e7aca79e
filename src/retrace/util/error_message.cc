#include "retrace/util/error_message.h"

#include <algorithm>

namespace retrace {

std::string OneLineMessage(const std::string& message) {
  std::string result;
  for (size_t i = 0; i < message.size();) {
    const auto byte = static_cast<unsigned char>(message[i]);
    size_t length = byte < 0x80 ? 1 : (byte >> 5) == 0x6 ? 2 : (byte >> 4) == 0xE ? 3 : (byte >> 3) == 0x1E ? 4 : 0;
    for (size_t k = 1; k < length; ++k) {
      if (i + k >= message.size() || (static_cast<unsigned char>(message[i + k]) & 0xC0) != 0x80) length = 0;
    }
    if (byte == '\n' || byte == '\r' || byte == '\t') {
      result += ' ';
    } else if (length == 0 || byte < 0x20 || byte == 0x7F) {
      result += '?';
    } else {
      result.append(message, i, length);
    }
    i += std::max<size_t>(length, 1);
  }
  return result.empty() ? "unknown error (no message)" : result;
}

}  // namespace retrace
