#include "signals.hpp"

#include <signal.h>
#include <time.h>
#include <unistd.h>

#include <atomic>

namespace sandcell::triaxial {

namespace {
std::atomic<int> g_signal{0};          // lock-free, so safe to write from a handler
std::atomic<long long> g_first_ns{0};  // CLOCK_MONOTONIC of the first signal
static_assert(std::atomic<int>::is_always_lock_free && std::atomic<long long>::is_always_lock_free);
constexpr long long k_same_request_ns = 1'000'000'000;

long long now_ns() {  // clock_gettime is async-signal-safe
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<long long>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}

extern "C" void on_stop_signal(int sig) {
  int none = 0;
  if (g_signal.compare_exchange_strong(none, sig)) {
    g_first_ns.store(now_ns());
    return;
  }
  // The same request often arrives twice (`scancel --full` signals the job script, which passes it
  // on, and triaxial itself): within a second it is the same request; later, out at once.
  if (now_ns() - g_first_ns.load() > k_same_request_ns) _exit(128 + sig);
}
}  // namespace

void install_stop_handlers() {
  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  for (int sig : {SIGTERM, SIGINT, SIGUSR1}) sigaction(sig, &action, nullptr);
}

bool stop_requested() { return g_signal.load(std::memory_order_relaxed) != 0; }
int stop_signal() { return g_signal.load(std::memory_order_relaxed); }
void clear_stop_request() { g_signal.store(0); }

}  // namespace sandcell::triaxial
