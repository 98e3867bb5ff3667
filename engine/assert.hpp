#pragma once
// One assert macro with a message. SANDCELL_ASSERT is active in Debug builds (NDEBUG unset);
// SANDCELL_CHECK is active in every build and is meant for cheap checks at setup or per step,
// never per element. Both report through a replaceable handler (abort by default; tests install
// one that throws so the check itself can be tested).
#include <string>

namespace sandcell {

using AssertHandler = void (*)(const char* file, int line, const char* expr, const std::string& message);

/// Installs a handler and returns the previous one. The default prints and calls std::abort().
AssertHandler set_assert_handler(AssertHandler handler);

[[noreturn]] void assert_fail(const char* file, int line, const char* expr, const std::string& message);

}  // namespace sandcell

#define SANDCELL_CHECK(cond, msg)                                           \
  do {                                                                      \
    if (!(cond)) ::sandcell::assert_fail(__FILE__, __LINE__, #cond, (msg)); \
  } while (false)

#ifdef NDEBUG
#define SANDCELL_ASSERT(cond, msg) \
  do {                             \
  } while (false)
#else
#define SANDCELL_ASSERT(cond, msg) SANDCELL_CHECK(cond, msg)
#endif
