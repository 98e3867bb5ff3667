#pragma once
// Numbers as the triaxial app writes them in messages, logs and index files.
#include <cstdio>
#include <string>

namespace sandcell::triaxial {

/// `v` printed with a printf format ("%.6g" unless told).
inline std::string num(double v, const char* format = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace sandcell::triaxial
