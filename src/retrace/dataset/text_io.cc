#include "retrace/dataset/text_io.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>

#include <fmt/format.h>

#include "retrace/util/error.h"

namespace retrace {
namespace {

bool IsBlank(const std::string& s) { return s.find_first_not_of(" \t") == std::string::npos; }

std::string Trim(const std::string& s) {
  const size_t begin = s.find_first_not_of(" \t");
  if (begin == std::string::npos) return "";
  const size_t end = s.find_last_not_of(" \t");
  return s.substr(begin, end - begin + 1);
}

double ParseNumber(const std::string& token, const TextLine& line, const std::string& file) {
  const std::string trimmed = Trim(token);
  if (trimmed.empty()) throw InputError(file, fmt::format("line {}: empty field", line.number));
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(trimmed.c_str(), &end);
  if (end != trimmed.c_str() + trimmed.size() || !std::isfinite(value) || errno == ERANGE) {
    std::string shown = trimmed.size() > 40 ? trimmed.substr(0, 40) + "..." : trimmed;
    throw InputError(file, fmt::format("line {}: '{}' is not a number", line.number, shown));
  }
  return value;
}

}  // namespace

std::vector<TextLine> ReadTextLines(const std::filesystem::path& path, bool skip_comments_and_empty) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path.string(), "is a folder, not a text file");
  std::ifstream in(path);
  if (!in.is_open()) {
    throw InputError(path.string(), std::filesystem::exists(path, ec) ? "cannot open the file" : "no such file");
  }
  std::vector<TextLine> lines;
  std::string text;
  size_t number = 0;
  while (std::getline(in, text)) {
    ++number;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    if (skip_comments_and_empty) {
      const std::string trimmed = Trim(text);
      if (trimmed.empty() || trimmed[0] == '#') continue;
    }
    lines.push_back({number, text});
  }
  if (in.bad()) throw InputError(path.string(), "read error");
  if (!skip_comments_and_empty) {
    while (!lines.empty() && IsBlank(lines.back().text)) lines.pop_back();
    for (const TextLine& line : lines) {
      if (IsBlank(line.text)) throw InputError(path.string(), fmt::format("line {}: empty line", line.number));
    }
  }
  return lines;
}

std::vector<double> ParseNumbers(const TextLine& line, char separator, const std::string& file) {
  std::vector<double> values;
  if (separator == ' ') {
    size_t pos = 0;
    const std::string& s = line.text;
    while (true) {
      pos = s.find_first_not_of(" \t", pos);
      if (pos == std::string::npos) break;
      const size_t end = s.find_first_of(" \t", pos);
      values.push_back(ParseNumber(s.substr(pos, end == std::string::npos ? std::string::npos : end - pos), line,
                                   file));
      if (end == std::string::npos) break;
      pos = end;
    }
  } else {
    size_t pos = 0;
    while (true) {
      const size_t end = line.text.find(separator, pos);
      values.push_back(ParseNumber(line.text.substr(pos, end == std::string::npos ? std::string::npos : end - pos),
                                   line, file));
      if (end == std::string::npos) break;
      pos = end + 1;
    }
  }
  return values;
}

std::vector<double> ReadTimestamps(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::vector<double> times;
  for (const TextLine& line : ReadTextLines(path)) {
    const std::vector<double> v = ParseNumbers(line, ' ', file);
    if (v.size() != 1) {
      throw InputError(file, fmt::format("line {}: expected one timestamp, found {} numbers", line.number, v.size()));
    }
    times.push_back(v[0]);
  }
  CheckInput(!times.empty(), file, "no timestamps in the file");
  return times;
}

std::string FormatKittiPose(const Rigid3d& world_from_cam) {
  const Matrix34d m = world_from_cam.ToMatrix();
  std::string s;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!s.empty()) s += ' ';
      s += fmt::format("{}", m(r, c));
    }
  }
  return s;
}

}  // namespace retrace
