#pragma once
// Lookups in a registry's table: rows with a `name` (std::string_view) and an `id` (an enum whose
// values are the rows' indices). The stress paths (systems/stress_paths.cpp), the rolling laws
// (systems/laws/rolling.hpp) and the triaxial app's test paths (apps/triaxial/protocol/paths.cpp)
// are such tables.
#include <cstddef>
#include <span>
#include <string>
#include <string_view>

namespace sandcell {

/// The row named `name`, or nullptr.
template <class Row>
const Row* find_named(std::span<const Row> rows, std::string_view name) {
  for (const Row& r : rows)
    if (r.name == name) return &r;
  return nullptr;
}

/// The names joined by `sep`, each between `quote`s (for messages).
template <class Row>
std::string joined_names(std::span<const Row> rows, std::string_view sep = ", ", std::string_view quote = "") {
  std::string out;
  for (const Row& r : rows) {
    if (!out.empty()) out += sep;
    out += std::string(quote) + std::string(r.name) + std::string(quote);
  }
  return out;
}

/// Whether row k holds id k for every k (a table indexed by its enum: static_assert it).
template <class Row, std::size_t N>
constexpr bool in_id_order(const Row (&rows)[N]) {
  for (std::size_t k = 0; k < N; ++k)
    if (static_cast<std::size_t>(rows[k].id) != k) return false;
  return true;
}

}  // namespace sandcell
