#pragma once

// Small line-oriented text readers shared by the dataset readers. Every problem throws InputError naming the file
// and the 1-based line number.

#include <filesystem>
#include <string>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct TextLine {
  size_t number = 0;  // 1-based line number in the file
  std::string text;   // without the line terminator ('\r' of Windows files removed too)
};

// All lines of a text file. With `skip_comments_and_empty`, lines that are empty (or whitespace) or whose first
// non-blank character is '#' are dropped; otherwise only a trailing empty line is dropped and an empty line in the
// middle is an error. Throws InputError when the file cannot be opened.
std::vector<TextLine> ReadTextLines(const std::filesystem::path& path, bool skip_comments_and_empty = false);

// The numbers of one line separated by `separator` (' ' means any run of blanks/tabs). A token that is not a finite
// number throws InputError(file, "line N: ...").
std::vector<double> ParseNumbers(const TextLine& line, char separator, const std::string& file);

// One number per line (KITTI times.txt and the optional times.txt of an image folder).
std::vector<double> ReadTimestamps(const std::filesystem::path& path);

// A pose as one KITTI line: 12 numbers of the row-major 3x4 [R|t], shortest exact decimal form.
std::string FormatKittiPose(const Rigid3d& world_from_cam);

}  // namespace retrace
