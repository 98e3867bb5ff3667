#include "engine/assert.hpp"

#include <atomic>
#include <cstdio>
#include <cstdlib>

namespace sandcell {
namespace {
void default_handler(const char* file, int line, const char* expr, const std::string& message) {
  std::fprintf(stderr, "sandcell: assertion failed at %s:%d: %s\n  %s\n", file, line, expr, message.c_str());
  std::abort();
}
std::atomic<AssertHandler> g_handler{&default_handler};
}  // namespace

AssertHandler set_assert_handler(AssertHandler handler) {
  return g_handler.exchange(handler ? handler : &default_handler);
}

void assert_fail(const char* file, int line, const char* expr, const std::string& message) {
  g_handler.load()(file, line, expr, message);
  // A handler that returns would let execution continue past a broken invariant.
  std::abort();
}

}  // namespace sandcell
