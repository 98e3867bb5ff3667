#pragma once
// Stop requests from outside: SIGTERM (a scheduler's time limit or preemption), SIGINT (Ctrl-C)
// and SIGUSR1 (`sbatch --signal=B:USR1@120`). The first one sets a flag that the step loops poll
// after every step: each job then finishes its step, writes its checkpoint, flushes its results
// and the process exits 3 ("stopped": continue with --resume). A second signal more than a second
// after the first exits at once (status 128 + the signal), for a user who does not want to wait;
// within a second it is taken as the same request delivered twice (a batch script passing on the
// signal that `scancel --full` also sent to triaxial).
namespace sandcell::triaxial {

/// Installs the handlers (idempotent); `triaxial_main` calls it for every run.
void install_stop_handlers();
/// Whether a stop was requested, and by which signal (0: none).
bool stop_requested();
int stop_signal();
/// Forgets a request (tests that run the app in-process several times).
void clear_stop_request();

}  // namespace sandcell::triaxial
