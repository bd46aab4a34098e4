#pragma once
// Checking PETSc calls from C++ code that reports errors by exception. Debian's PETSc is built for C, so
// PETSc's own PetscCallThrow is not available.
#include <petscsys.h>

#include <cerrno>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#define CELLFSI_PETSC(...)                                                                             \
  do {                                                                                                 \
    const PetscErrorCode cellfsi_ierr_ = __VA_ARGS__;                                                  \
    if (PetscUnlikely(cellfsi_ierr_)) ::cellfsi::throw_petsc_error(cellfsi_ierr_, __FILE__, __LINE__); \
  } while (0)

#include <initializer_list>
#include <sstream>
#include <utility>

namespace cellfsi {

namespace detail {
/// The first message of the PETSc error being handled (record_petsc_errors), cleared once thrown.
inline std::string& pending_petsc_message() {
  static std::string m;
  return m;
}
inline PetscErrorCode record_pending(MPI_Comm, int, const char*, const char*, PetscErrorCode n,
                                     PetscErrorType p, const char* mess, void*) {
  // A new error starts a new message (one whose code was ignored must not be reported with the next).
  std::string& m = detail::pending_petsc_message();
  if (p == PETSC_ERROR_INITIAL) m.clear();
  if (m.empty() && mess) m = mess;
  return n;
}
}  // namespace detail

/// From now on PETSc errors are recorded instead of printed as a traceback; CELLFSI_PETSC's exceptions carry
/// the message (call once, after PetscInitialize).
inline void record_petsc_errors() { PetscPushErrorHandler(detail::record_pending, nullptr); }

/// Throws for a failed PETSc call: std::invalid_argument for an unknown type (a misspelt -..._type option,
/// named with its value), std::runtime_error with PETSc's message otherwise.
[[noreturn]] inline void throw_petsc_error(PetscErrorCode code, const char* file, int line) {
  std::string message;
  std::swap(message, detail::pending_petsc_message());
  if (code == PETSC_ERR_ARG_UNKNOWN_TYPE && !message.empty()) {
    // "Unable to find requested KSP type gmress": the option with that value.
    const std::string value = message.substr(message.find_last_of(' ') + 1);
    char* all = nullptr;
    std::string option;
    if (PetscOptionsGetAll(nullptr, &all) == 0 && all) {
      std::istringstream in(all);
      std::string prev, tok;
      while (in >> tok) {
        if (tok == value && prev.size() > 1 && prev[0] == '-') option = prev;
        prev = tok;
      }
      PetscFree(all);
    }
    throw std::invalid_argument(
        (option.empty() ? std::string("a type") : "option " + option + " = " + value) +
        " is invalid: " + message + " (-help lists the types this PETSc has)");
  }
  // A value PETSc (or a package's interface) checks when it applies an option, e.g. -..._mat_mumps_icntl_7 1
  // ("Valid values are 0=AMD, 2=AMF, ..."): bad input, not a failure of the run.
  if (code == PETSC_ERR_ARG_OUTOFRANGE && message.find("Valid values") != std::string::npos)
    throw std::invalid_argument("a solver option's value is invalid: " + message);
  // A solver package that cannot factor the matrix it was given (e.g. -..._pc_factor_mat_solver_type superlu
  // on a BAIJ matrix: "MatSolverType superlu does not support matrix type seqbaij"): bad input too.
  if (code == PETSC_ERR_MISSING_FACTOR)
    throw std::invalid_argument("a solver option's value is invalid: " + message);
  // Bad input found inside a callback PETSc called (a cellfsi PC type's set-up): its message as it was.
  if (code == PETSC_ERR_USER_INPUT && !message.empty()) throw std::invalid_argument(message);
  throw std::runtime_error("PETSc error " + std::to_string(code) + " at " + file + ":" +
                           std::to_string(line) + (message.empty() ? std::string() : ": " + message));
}

/// Registers a PETSc log event (shown by -log_view) under a class of that name; call once per event, e.g. to
/// initialise a function-local static.
inline PetscLogEvent register_log_event(const char* class_name, const char* event_name) {
  PetscClassId id = 0;
  PetscLogEvent e = 0;
  CELLFSI_PETSC(PetscClassIdRegister(class_name, &id));
  CELLFSI_PETSC(PetscLogEventRegister(event_name, id, &e));
  return e;
}

/// RAII begin/end of a log event (ended on a throw too).
class EventScope {
 public:
  explicit EventScope(PetscLogEvent e) : e_(e) { PetscLogEventBegin(e_, 0, 0, 0, 0); }
  ~EventScope() { PetscLogEventEnd(e_, 0, 0, 0, 0); }
  EventScope(const EventScope&) = delete;
  EventScope& operator=(const EventScope&) = delete;

 private:
  PetscLogEvent e_;
};

namespace detail {
inline PetscErrorCode record_first_message(MPI_Comm, int, const char*, const char*, PetscErrorCode n,
                                           PetscErrorType, const char* mess, void* ctx) {
  auto* m = static_cast<std::string*>(ctx);
  if (m->empty() && mess) *m = mess;
  return n;
}
}  // namespace detail

/// Runs `call` (which returns a PetscErrorCode, e.g. a function reading options) with PETSc's error handler
/// replaced by one that records the message instead of printing a traceback. On error it finds, among
/// `probes` (option, kind: 'i' integer, 'r' real, 'I' integer list, 'R' real list, 'b' boolean, 'B' boolean
/// list, 's' word, 'S' list of words), the option whose value does not parse and throws std::invalid_argument
/// naming it, its value and PETSc's reason (for input such as "-fluid_degree abc"). Used by OptionTable.
template <class Call>
void call_reporting_input_errors(Call&& call, const std::vector<std::pair<std::string, char>>& probes) {
  std::string message;
  PetscPushErrorHandler(detail::record_first_message, &message);
  const PetscErrorCode ierr = call();
  PetscPopErrorHandler();
  auto what_of = [](char kind) {
    return kind == 'i'   ? "an integer"
           : kind == 'r' ? "a number"
           : kind == 'b' ? "true or false"
           : kind == 'B' ? "comma-separated true/false (or 1/0)"
           : kind == 's' ? "a word"
           : kind == 'S' ? "comma-separated words"
                         : "comma-separated numbers";
  };
  if (!ierr) {
    // PETSc keeps the default for a value option given without a value ("-dt" at the end of the line, or
    // followed by another option): refuse it (booleans may stand alone).
    for (const auto& [option, kind] : probes) {
      if (kind == 'b') continue;
      PetscBool has = PETSC_FALSE, set = PETSC_FALSE;
      char value[64] = "";
      PetscOptionsHasName(nullptr, nullptr, option.c_str(), &has);
      if (has) PetscOptionsGetString(nullptr, nullptr, option.c_str(), value, sizeof value, &set);
      if (has && value[0] == '\0')
        throw std::invalid_argument("option " + option + " has no value; valid: " + what_of(kind));
      if (has && kind == 'i') {
        // An integer beyond PetscInt wraps silently (-output_every 10000000000).
        PetscInt v = 0;
        PetscOptionsGetInt(nullptr, nullptr, option.c_str(), &v, nullptr);
        errno = 0;
        const long long exact = std::strtoll(value, nullptr, 10);
        if (errno == ERANGE || exact != static_cast<long long>(v))
          throw std::invalid_argument("option " + option + " = " + value +
                                      " is invalid; valid: an integer up to " +
                                      std::to_string(std::numeric_limits<PetscInt>::max()));
      }
    }
    return;
  }
  for (const auto& [option, kind] : probes) {
    if (kind == 's' || kind == 'S') continue;  // any text parses
    const char* name = option.c_str();
    std::string why;
    PetscPushErrorHandler(detail::record_first_message, &why);
    PetscErrorCode e = 0;
    PetscInt iv[8], n = 8;
    PetscReal rv[8];
    PetscBool bv[8] = {};
    switch (kind) {
      case 'i':
        e = PetscOptionsGetInt(nullptr, nullptr, name, iv, nullptr);
        break;
      case 'r':
        e = PetscOptionsGetReal(nullptr, nullptr, name, rv, nullptr);
        break;
      case 'I':
        e = PetscOptionsGetIntArray(nullptr, nullptr, name, iv, &n, nullptr);
        break;
      case 'R':
        e = PetscOptionsGetRealArray(nullptr, nullptr, name, rv, &n, nullptr);
        break;
      case 'B':
        e = PetscOptionsGetBoolArray(nullptr, nullptr, name, bv, &n, nullptr);
        break;
      default:
        e = PetscOptionsGetBool(nullptr, nullptr, name, bv, nullptr);
        break;
    }
    PetscPopErrorHandler();
    if (e) {
      char value[256] = "";
      PetscOptionsGetString(nullptr, nullptr, name, value, sizeof value, nullptr);
      const char* what = what_of(kind);
      throw std::invalid_argument("option " + std::string(name) + " = " + value +
                                  " is invalid; valid: " + what + " (" + why + ")");
    }
  }
  throw std::invalid_argument("invalid option value: " +
                              (message.empty() ? std::string("(no message)") : message));
}

}  // namespace cellfsi
