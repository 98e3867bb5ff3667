#include "engine/scratch.hpp"

#include <stdexcept>

namespace sandcell {

namespace detail {
std::size_t next_scratch_slot() {
  static std::atomic<std::size_t> next{0};
  return next.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace detail

Scratch::~Scratch() {
  for (auto& s : slots_) delete s.load(std::memory_order_relaxed);
}

void Scratch::check_slot(std::size_t k) {
  if (k >= k_max_types)
    throw std::length_error("Scratch: more than " + std::to_string(k_max_types) +
                            " scratch types in this process: raise Scratch::k_max_types");
}

}  // namespace sandcell
