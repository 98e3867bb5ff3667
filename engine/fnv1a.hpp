#pragma once
// FNV-1a, 64 bit, over raw bytes: the state digests of dem-bench and the checksums of checkpoints.
// Not cryptographic; it detects accidental changes (a flipped bit, a different result).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace sandcell {

struct Fnv1a {
  std::uint64_t h = 0xcbf29ce484222325ull;
  void bytes(const void* data, std::size_t size) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t k = 0; k < size; ++k) h = (h ^ b[k]) * 0x100000001b3ull;
  }
  /// The elements' bytes, in order (no length).
  template <class T>
  void array(const std::vector<T>& v) {
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
};

/// A digest as 16 lowercase hex digits (how results files record them).
inline std::string hex_digest(std::uint64_t h) {
  char s[17];
  std::snprintf(s, sizeof s, "%016llx", static_cast<unsigned long long>(h));
  return s;
}

}  // namespace sandcell
