#pragma once

// Errors at the boundary of retrace.
//
// Bad input (an unreadable image, an inconsistent calibration file, a corrupt map, a bad scenario file) throws
// `InputError` where it is read. The message is one line that names the file and the problem; the command-line
// `main` turns it into "retrace: error: <message>" and a non-zero exit code. Normal outcomes of the algorithms
// (a track that fails, a geometry that cannot be estimated, being lost) are returned as values, never thrown.

#include <stdexcept>
#include <string>

namespace retrace {

class InputError : public std::runtime_error {
 public:
  // `source` is the file (or other input) at fault, `problem` what is wrong with it.
  InputError(const std::string& source, const std::string& problem)
      : std::runtime_error(source.empty() ? problem : source + ": " + problem), source_(source), problem_(problem) {}

  const std::string& source() const { return source_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string source_;
  std::string problem_;
};

// Throws InputError(source, problem) unless `condition` holds.
inline void CheckInput(bool condition, const std::string& source, const std::string& problem) {
  if (!condition) throw InputError(source, problem);
}

}  // namespace retrace
