#pragma once

// How much memory the process holds, for summaries ("peak memory 180 MB") and tests that a long run stays flat.

#include <cstdint>

namespace retrace {

// Resident set size now, in bytes (Linux /proc/self/statm); 0 where it cannot be read.
int64_t CurrentResidentBytes();

// Largest resident set size so far, in bytes (getrusage); 0 where it cannot be read.
int64_t PeakResidentBytes();

}  // namespace retrace
