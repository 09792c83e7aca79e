#pragma once

namespace retrace {

// Version of retrace, "MAJOR.MINOR.PATCH" (from CMake's project()).
const char* Version();

}  // namespace retrace
