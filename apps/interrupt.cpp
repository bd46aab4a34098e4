#include "apps/interrupt.hpp"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>

namespace cellfsi::app {

namespace {

constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGUSR1};

volatile std::sig_atomic_t g_signal = 0;    // what stops the run (the first one)
volatile std::sig_atomic_t g_requests = 0;  // stop signals so far (SIGPIPE is none: nobody asked)
volatile std::sig_atomic_t g_announce = 0;
volatile std::sig_atomic_t g_stepping = 0;
bool g_ignored[NSIG] = {};

/// Async-signal-safe: write() only.
void say(const char* text) {
  ssize_t ignored = write(STDERR_FILENO, text, std::strlen(text));
  (void)ignored;
}

/// `requested`: by a stop signal, so that a second one ends the process at once.
void announce(const char* what, bool requested) {
  if (!g_announce) return;
  say("cellfsi: ");
  say(what);
  say(g_stepping ? "; finishing the current step, then writing the summary" : " during set-up; stopping");
  say(requested ? " (signal again to end at once)\n" : "\n");
}

extern "C" void on_stop_signal(int sig) {
  const int saved_errno = errno;
  if (g_requests != 0) {
    // A second request: the default action (the process ends now).
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  g_requests = 1;
  if (g_signal == 0) g_signal = sig;
  announce("stop requested", true);
  errno = saved_errno;
}

/// SIGPIPE: a write to a pipe nobody reads any more. If that is standard output or error (poll reports an
/// error on the write end of a pipe without readers), the stream is pointed at /dev/null, so that printing
/// neither fails nor signals again, and the run stops as on a request. Any other pipe or socket (MPI's) is
/// none of this handler's business: the failed write reports it.
extern "C" void on_broken_pipe(int) {
  const int saved_errno = errno;
  bool broken = false;
  for (int fd : {STDOUT_FILENO, STDERR_FILENO}) {
    pollfd p{fd, 0, 0};
    if (poll(&p, 1, 0) == 1 && (p.revents & (POLLERR | POLLHUP)) != 0) {
      const int null = open("/dev/null", O_WRONLY);
      if (null >= 0) {
        dup2(null, fd);
        close(null);
      }
      broken = true;
    }
  }
  if (broken && g_signal == 0) {
    g_signal = SIGPIPE;
    announce("standard output closed (SIGPIPE), no more progress lines", false);
  }
  errno = saved_errno;
}

}  // namespace

void record_ignored_signals() {
  for (int sig : kStopSignals) {
    struct sigaction old;
    if (sigaction(sig, nullptr, &old) == 0) g_ignored[sig] = old.sa_handler == SIG_IGN;
  }
}

void install_stop_handlers(bool announce) {
  g_announce = announce ? 1 : 0;
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;  // system calls in progress (file writes, MPI) resume
  for (int sig : kStopSignals) {
    // An ignored signal stays so (PETSc installed its handler over it since).
    sa.sa_handler = g_ignored[sig] ? SIG_IGN : on_stop_signal;
    sigaction(sig, &sa, nullptr);
  }
  // Even if started with SIGPIPE ignored: a run whose output nobody reads stops rather than going on for
  // hours while the shell waits for it.
  sa.sa_handler = on_broken_pipe;
  sigaction(SIGPIPE, &sa, nullptr);
}

void mark_time_stepping() { g_stepping = 1; }

int stop_signal() { return static_cast<int>(g_signal); }

int agreed_stop_signal(MPI_Comm comm) {
  int sig = stop_signal();
  MPI_Allreduce(MPI_IN_PLACE, &sig, 1, MPI_INT, MPI_MAX, comm);
  return sig;
}

std::string signal_name(int signal) {
  switch (signal) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    case SIGHUP:
      return "SIGHUP";
    case SIGPIPE:
      return "SIGPIPE";
    case SIGUSR1:
      return "SIGUSR1";
    default:
      return "signal " + std::to_string(signal);
  }
}

}  // namespace cellfsi::app
