#pragma once
// prefetch_for_write: asks for the cache line holding p in a state that can be written (read for
// ownership) ahead of the store.
//
// Why the particle passes need it: in a world stepped on more than one thread, a particle's
// position, velocity and spin are read by every core whose contact chunks reach it, so when a
// pass writes them the line must first be taken away from the other core (an invalidation
// round trip). A plain load-prefetch brings the line shared and leaves that round trip to the
// store; PREFETCHW starts it early, so it overlaps the work on the particles before. On one thread
// no other core holds the line and the prefetch costs almost nothing.
// On x86-64 the instruction is PREFETCHW (executed as a no-op by the Intel CPUs before Broadwell
// that do not report it); elsewhere GCC's write prefetch.
namespace sandcell {

[[gnu::always_inline]] inline void prefetch_for_write(const void* p) {
#if defined(__x86_64__)
  asm volatile("prefetchw %0" : : "m"(*static_cast<const char*>(p)));
#else
  __builtin_prefetch(p, 1);
#endif
}

}  // namespace sandcell
