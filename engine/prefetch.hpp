#pragma once
// prefetch_for_write: asks for the cache line holding p in a state that can be written (read for
// ownership) ahead of the store.
//
// Why the particle passes need it: in a world stepped on more than one thread, a particle's
// position, velocity and spin are read by every core whose contact chunks reach it, so when a
// pass writes them the line must first be taken away from the other core (an invalidation
// round trip). A plain prefetch brings the line shared and leaves that round trip to the store
// (no gain measured with it); PREFETCHW starts it early, so
// it overlaps the work on the particles before. On one thread no other core holds the line and
// the prefetch costs almost nothing.
// PREFETCHW is reported by CPUID from Intel Broadwell and AMD K8 on, and outside any -march level:
// a pass asks cpu_has_prefetchw() once and picks its loop, prefetch_for_write<true> (PREFETCHW) or
// <false> (GCC's write prefetch, a plain prefetch without -mprfchw; a hint on every CPU).
namespace sandcell {

/// Whether this CPU reports PREFETCHW (CPUID 0x80000001 ECX bit 8); false off x86-64.
bool cpu_has_prefetchw();

template <bool Exclusive>
[[gnu::always_inline]] inline void prefetch_for_write(const void* p) {
#if defined(__x86_64__)
  if constexpr (Exclusive) {
    asm volatile("prefetchw %0" : : "m"(*static_cast<const char*>(p)));
    return;
  }
#endif
  __builtin_prefetch(p, 1);
}

}  // namespace sandcell
