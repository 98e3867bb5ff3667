#pragma once
// Scratch: what systems keep between steps that is rebuilt, never checkpointed. Buffers keep their
// capacity between steps, so nothing is allocated inside a step once warmed up.
//
// The engine does not know the systems' buffers: Scratch holds one object of each type a system
// asks for, created (value-initialized) on first use and owned by the Scratch.
//   - A type shared between systems names the component that its access is declared under
//     (`static constexpr Component component = ...`) and is reached through read<T>() / write<T>(),
//     checked like State access, so the step graph orders its writer before its readers.
//   - A system's private buffers (e.g. the broadphase bins) are reached through own<T>(): no check,
//     no ordering; only that system touches them.
// World and the systems share two plain members: `error`, set by a system that finds the scene
// cannot be continued (World stops with it, naming the step), and `batching` (below).
#include "components/fields.hpp"
#include "engine/access.hpp"

#include <array>
#include <atomic>
#include <cstddef>
#include <memory>
#include <mutex>
#include <string>

namespace sandcell {

namespace detail {
/// The next free slot index (one per scratch type, process-wide, thread-safe).
std::size_t next_scratch_slot();
template <class T>
std::size_t scratch_slot() {
  static const std::size_t slot = next_scratch_slot();
  return slot;
}
}  // namespace detail

class Scratch {
 public:
  /// At most this many distinct scratch types in one process.
  static constexpr std::size_t k_max_types = 32;

  Scratch() = default;
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  ~Scratch();

  /// Set by a system when the scene cannot be continued (an instability, a cell too narrow);
  /// World checks it after each step and throws SimulationError with it.
  std::string error;
  /// Set by World for the length of a World::step_until call in which a system that declares
  /// `deferred_to` may leave its work to that system's next run (engine/system.hpp); World then
  /// calls its `flush` before returning.
  bool batching = false;

  /// A shared scratch type, read (T::component must be in the running system's read or write set).
  template <class T>
  const T& read() const {
    check_access(T::component, false);
    return slot<T>();
  }
  /// A shared scratch type, written (T::component must be in the running system's write set).
  template <class T>
  T& write() {
    check_access(T::component, true);
    return slot<T>();
  }
  /// A system's private buffers (not access-checked: no other system may touch them).
  template <class T>
  T& own() {
    return slot<T>();
  }
  template <class T>
  const T& own() const {
    return slot<T>();
  }
  /// Whether an object of type T has been created (e.g. a system that never ran).
  template <class T>
  bool has() const {
    const std::size_t k = detail::scratch_slot<T>();
    return k < k_max_types && slots_[k].load(std::memory_order_acquire) != nullptr;
  }

 private:
  struct Holder {
    virtual ~Holder() = default;
  };
  template <class T>
  struct Typed final : Holder {
    T value{};
  };

  template <class T>
  T& slot() const {
    const std::size_t k = detail::scratch_slot<T>();
    Holder* h = k < k_max_types ? slots_[k].load(std::memory_order_acquire) : nullptr;
    if (!h) h = create(k, [] { return static_cast<Holder*>(new Typed<T>()); });
    return static_cast<Typed<T>*>(h)->value;
  }
  // Creates slot k under the lock unless another thread did first (two unordered readers of a type
  // nobody wrote yet); throws std::length_error beyond k_max_types.
  template <class Make>
  Holder* create(std::size_t k, Make make) const {
    check_slot(k);
    std::lock_guard lock(create_mutex_);
    Holder* h = slots_[k].load(std::memory_order_acquire);
    if (!h) {
      h = make();
      slots_[k].store(h, std::memory_order_release);
    }
    return h;
  }
  static void check_slot(std::size_t k);

  mutable std::array<std::atomic<Holder*>, k_max_types> slots_{};
  mutable std::mutex create_mutex_;
};

}  // namespace sandcell
