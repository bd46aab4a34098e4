#pragma once
// One module's options, declared once in a table: name, kind, where the value lives (its value before
// reading is the default, so no default is written twice), help text and valid range. Reading (through
// PETSc's options database, which the command line and a scene YAML file feed), -help (each option is listed
// in PETSc's options block with its default and help, and with "[valid: ...]" where the table states a
// range or choices), the checks and every error message come from the table:
//
//   FluidOptions o;                                   // defaults: the struct's initialisers
//   OptionTable t("Fluid (VMS Navier-Stokes; CGS units)", "fluid_");
//   t.real("density", o.density, "rho_1 [g/cm^3]", positive("[g/cm^3]"))
//    .reals("body_force", force, "Body force per volume fx,fy[,fz] [dyn/cm^3]", [&] { return dim; });
//   t.read();  // throws std::invalid_argument "option -fluid_density = -1 is invalid; valid: > 0 [g/cm^3]"
//
// A value that does not parse ("-fluid_degree abc"), an option given without its value ("-dt" at the end of
// the line), an integer beyond PetscInt, a list of the wrong length, a word outside its choices and a value
// outside its range are each refused with one message naming the option. Checks between options (a body
// inside the domain, a thickness below the semi-axes) stay with the module, through OptionTable::bad.
#include <petscsys.h>

#include <cmath>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/petsc_error.hpp"

namespace cellfsi {

/// What is valid for a value: the test, and the words that say it in an error message ("> 0 [s]").
template <class T>
struct Valid {
  std::function<bool(const T&)> ok;
  std::string text;
};

inline std::string option_value_text(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

inline std::string with_unit(std::string text, const std::string& unit) {
  return unit.empty() ? text : text + " " + unit;
}
inline Valid<double> positive(const std::string& unit = "") {
  return {[](const double& v) { return v > 0 && std::isfinite(v); }, with_unit("> 0", unit)};
}
inline Valid<double> non_negative(const std::string& unit = "") {
  return {[](const double& v) { return v >= 0 && std::isfinite(v); }, with_unit(">= 0", unit)};
}
inline Valid<double> finite(const std::string& unit = "") {
  return {[](const double& v) { return std::isfinite(v); }, with_unit("a finite number", unit)};
}
/// lo <= v <= hi (note: added to the message, e.g. why the bounds are where they are).
inline Valid<double> between(double lo, double hi, const std::string& unit = "",
                             const std::string& note = "") {
  return {[lo, hi](const double& v) { return v >= lo && v <= hi; },
          with_unit(with_unit(option_value_text(lo) + " ... " + option_value_text(hi), unit), note)};
}
/// A material constant (a density, a viscosity, a modulus) in CGS units: lo <= v <= hi, bounds far outside
/// any cell or liquid, with the reason in the message (`why`, or the default's). A positive value that is
/// only a number, not a material, ran: G = 1e-310 (a denormal) "completed" as a steady cell, a density of
/// 1e300 ended in a NaN residual that named no option.
inline Valid<double> material(double lo, double hi, const std::string& unit, const std::string& why = "") {
  return between(
      lo, hi, unit,
      "(a material constant in CGS units; " +
          (why.empty() ? "far outside these bounds the solver's products of it leave double precision"
                       : why) +
          ")");
}
/// v >= lo (note: added to the message, e.g. "(0: never)").
inline Valid<long long> at_least(long long lo, const std::string& note = "") {
  return {[lo](const long long& v) { return v >= lo; }, with_unit(">= " + std::to_string(lo), note)};
}
/// lo <= v <= hi.
inline Valid<long long> int_between(long long lo, long long hi, const std::string& note = "") {
  return {[lo, hi](const long long& v) { return v >= lo && v <= hi; },
          with_unit(std::to_string(lo) + " ... " + std::to_string(hi), note)};
}

/// Refuses an option's value: std::invalid_argument "option -NAME = VALUE is invalid; valid: VALID".
[[noreturn]] inline void bad_option(const std::string& name, const std::string& value,
                                    const std::string& valid) {
  throw std::invalid_argument("option -" + name + " = " + value + " is invalid; valid: " + valid);
}

class OptionTable {
 public:
  /// title: the section in -help; prefix: prepended to every name (e.g. "solid_membrane_").
  explicit OptionTable(std::string title, std::string prefix = "")
      : title_(std::move(title)), prefix_(std::move(prefix)) {}
  // The entries refer to the table and to the values they fill: neither copied nor moved.
  OptionTable(const OptionTable&) = delete;
  OptionTable& operator=(const OptionTable&) = delete;

  OptionTable& real(const std::string& name, double& value, std::string help, Valid<double> valid = {}) {
    return scalar<double, PetscReal>('r', name, value, std::move(help), std::move(valid));
  }
  OptionTable& integer(const std::string& name, int& value, std::string help, Valid<long long> valid = {}) {
    return scalar<int, PetscInt>('i', name, value, std::move(help), std::move(valid));
  }

  OptionTable& flag(const std::string& name, bool& value, std::string help) {
    add(name, 'b', std::move(help));
    entries_.back().read = [this, &value,
                            i = entries_.size() - 1](PetscOptionItems* PetscOptionsObject) -> PetscErrorCode {
      PetscFunctionBeginUser;
      Entry& me = entries_[i];
      PetscBool v = value ? PETSC_TRUE : PETSC_FALSE;
      PetscCall(PetscOptionsBool(full(me).c_str(), me.help.c_str(), nullptr, v, &v, &me.given_flag));
      value = v == PETSC_TRUE;
      PetscFunctionReturn(0);
    };
    return *this;
  }

  /// A word; with choices, one of them (listed in -help and in the error message).
  OptionTable& text(const std::string& name, std::string& value, std::string help,
                    std::vector<std::string> choices = {}) {
    add(name, 's', std::move(help), choices.empty() ? "" : one_of(choices));
    Entry& e = entries_.back();
    e.read = [this, &value, i = entries_.size() - 1](PetscOptionItems* PetscOptionsObject) -> PetscErrorCode {
      PetscFunctionBeginUser;
      Entry& me = entries_[i];
      std::vector<char> buf(PETSC_MAX_PATH_LEN, '\0');
      value.copy(buf.data(), buf.size() - 1);
      PetscCall(PetscOptionsString(full(me).c_str(), me.help.c_str(), nullptr, buf.data(), buf.data(),
                                   buf.size(), &me.given_flag));
      value = buf.data();
      PetscFunctionReturn(0);
    };
    e.check = [this, &value, choices, name] {
      if (choices.empty()) return;
      for (const std::string& c : choices)
        if (value == c) return;
      bad(name, value.empty() ? "''" : value, one_of(choices));
    };
    return *this;
  }

  /// Lists: `count()` is the number of values required when the option is given (evaluated after reading,
  /// so it may depend on another option of the table, e.g. the dimension); every value is checked by `each`.
  OptionTable& reals(const std::string& name, std::vector<double>& value, std::string help,
                     std::function<int()> count, Valid<double> each = {}) {
    return list<double, PetscReal>('R', name, value, std::move(help), std::move(count), valid_text(each),
                                   [this, each, name](double v) {
                                     if (each.ok && !each.ok(v)) bad(name, option_value_text(v), each.text);
                                   });
  }
  OptionTable& integers(const std::string& name, std::vector<int>& value, std::string help,
                        std::function<int()> count, Valid<long long> each = {}) {
    return list<int, PetscInt>('I', name, value, std::move(help), std::move(count), valid_text(each),
                               [this, each, name](int v) {
                                 if (each.ok && !each.ok(v)) bad(name, std::to_string(v), each.text);
                               });
  }
  OptionTable& flags(const std::string& name, std::vector<bool>& value, std::string help,
                     std::function<int()> count) {
    return list<bool, PetscBool>('B', name, value, std::move(help), std::move(count), "", [](bool) {});
  }
  /// A list of words, at most max_count of them (any count up to it).
  OptionTable& texts(const std::string& name, std::vector<std::string>& value, std::string help,
                     int max_count) {
    add(name, 'S', std::move(help));
    entries_.back().read = [this, &value, max_count,
                            i = entries_.size() - 1](PetscOptionItems* PetscOptionsObject) -> PetscErrorCode {
      PetscFunctionBeginUser;
      Entry& me = entries_[i];
      std::vector<char*> words(max_count + 1, nullptr);  // one more, so that an extra word is seen
      PetscInt n = max_count + 1;
      PetscCall(PetscOptionsStringArray(full(me).c_str(), me.help.c_str(), nullptr, words.data(), &n,
                                        &me.given_flag));
      if (me.given_flag) {
        value.clear();
        for (PetscInt k = 0; k < n; ++k) {
          value.emplace_back(words[k] ? words[k] : "");
          PetscFree(words[k]);
        }
        me.count = static_cast<int>(n);
      }
      PetscFunctionReturn(0);
    };
    entries_.back().check = [this, max_count, i = entries_.size() - 1] {
      const Entry& me = entries_[i];
      if (me.count > max_count)
        bad(me.name, std::to_string(me.count) + " values", "at most " + std::to_string(max_count));
    };
    return *this;
  }

  /// Reads every option (one PETSc options block; -help lists them), then checks each in declaration order;
  /// throws std::invalid_argument naming the option at the first bad value. Options not given keep their
  /// value (the default).
  void read() {
    std::vector<std::pair<std::string, char>> probes;
    for (const Entry& e : entries_) probes.emplace_back(full(e), e.kind);
    call_reporting_input_errors(
        [this]() -> PetscErrorCode {
          PetscFunctionBeginUser;
          PetscOptionsBegin(PETSC_COMM_WORLD, nullptr, title_.c_str(), nullptr);
          for (Entry& e : entries_) PetscCall(e.read(PetscOptionsObject));
          PetscOptionsEnd();
          PetscFunctionReturn(0);
        },
        probes);
    check();
  }

  /// The checks alone, on the values as they are (settings made in code, not read).
  void check() const {
    for (const Entry& e : entries_)
      if (e.check) e.check();
  }

  /// Whether the option was given (on the command line or in the scene file).
  bool given(const std::string& name) const {
    for (const Entry& e : entries_)
      if (e.name == name) return e.given_flag == PETSC_TRUE;
    throw std::logic_error("OptionTable: no option '" + name + "' in '" + title_ + "'");
  }
  /// Refuses a value of this table's option `name` (without the prefix), e.g. after a check between options.
  [[noreturn]] void bad(const std::string& name, const std::string& value, const std::string& valid) const {
    bad_option(prefix_ + name, value, valid);
  }
  const std::string& prefix() const { return prefix_; }

  /// "a, b or c".
  static std::string one_of(const std::vector<std::string>& words) {
    std::string s;
    for (std::size_t i = 0; i < words.size(); ++i)
      s += (i == 0 ? "" : i + 1 == words.size() ? " or " : ", ") + words[i];
    return s;
  }

 private:
  struct Entry {
    std::string name;
    char kind = 'r';  // call_reporting_input_errors' kinds, and 's' word, 'S' list of words
    std::string help;  // as -help prints it: the help text, then "[valid: ...]" where the table states it
    std::function<PetscErrorCode(PetscOptionItems*)> read;  // inside the options block
    std::function<void()> check;
    PetscBool given_flag = PETSC_FALSE;
    int count = 0;  // words read ('S')
  };

  std::string full(const Entry& e) const { return "-" + prefix_ + e.name; }
  /// valid: what the table states is valid (a Valid's text, a word's choices; "" if nothing).
  void add(const std::string& name, char kind, std::string help, const std::string& valid = "") {
    for (const Entry& e : entries_)
      if (e.name == name) throw std::logic_error("OptionTable '" + title_ + "': option '" + name + "' twice");
    Entry e;
    e.name = name;
    e.kind = kind;
    e.help = valid.empty() ? std::move(help) : std::move(help) + " [valid: " + valid + "]";
    entries_.push_back(std::move(e));
  }

  /// What -help states as valid for a Valid: its text if it checks anything.
  template <class V>
  static std::string valid_text(const Valid<V>& valid) {
    return valid.ok ? valid.text : "";
  }

  /// A number: PETSc reads it as P (PetscReal, PetscInt; PetscInt is int here, and larger input is refused by
  /// the probes), valid checks it as V.
  template <class T, class P, class V>
  OptionTable& scalar(char kind, const std::string& name, T& value, std::string help, Valid<V> valid) {
    add(name, kind, std::move(help), valid_text(valid));
    Entry& e = entries_.back();
    e.read = [this, &value, i = entries_.size() - 1](PetscOptionItems* PetscOptionsObject) -> PetscErrorCode {
      PetscFunctionBeginUser;
      Entry& me = entries_[i];
      P v = value;
      if constexpr (std::is_same_v<P, PetscReal>)
        PetscCall(PetscOptionsReal(full(me).c_str(), me.help.c_str(), nullptr, v, &v, &me.given_flag));
      else
        PetscCall(PetscOptionsInt(full(me).c_str(), me.help.c_str(), nullptr, v, &v, &me.given_flag));
      value = static_cast<T>(v);
      PetscFunctionReturn(0);
    };
    e.check = [this, &value, valid, name] {
      if (!valid.ok || valid.ok(value)) return;
      if constexpr (std::is_floating_point_v<T>)
        bad(name, option_value_text(value), valid.text);
      else
        bad(name, std::to_string(value), valid.text);
    };
    return *this;
  }

  template <class T, class P, class Each>
  OptionTable& list(char kind, const std::string& name, std::vector<T>& value, std::string help,
                    std::function<int()> count, const std::string& valid, Each each) {
    add(name, kind, std::move(help), valid);
    Entry& e = entries_.back();
    e.read = [this, &value, i = entries_.size() - 1](PetscOptionItems* PetscOptionsObject) -> PetscErrorCode {
      PetscFunctionBeginUser;
      Entry& me = entries_[i];
      constexpr int kMax = 16;
      P buf[kMax + 1] = {};  // one more than any valid count, so that an extra value is seen
      for (std::size_t k = 0; k < value.size() && k < static_cast<std::size_t>(kMax); ++k)
        buf[k] = static_cast<P>(static_cast<T>(value[k]));
      PetscInt n = kMax + 1;
      if constexpr (std::is_same_v<P, PetscReal>)
        PetscCall(PetscOptionsRealArray(full(me).c_str(), me.help.c_str(), nullptr, buf, &n, &me.given_flag));
      else if constexpr (std::is_same_v<P, PetscInt>)
        PetscCall(PetscOptionsIntArray(full(me).c_str(), me.help.c_str(), nullptr, buf, &n, &me.given_flag));
      else
        PetscCall(PetscOptionsBoolArray(full(me).c_str(), me.help.c_str(), nullptr, buf, &n, &me.given_flag));
      if (me.given_flag) {
        value.assign(n, T{});
        for (PetscInt k = 0; k < n; ++k) {
          if constexpr (std::is_same_v<P, PetscBool>)
            value[k] = buf[k] == PETSC_TRUE;
          else
            value[k] = static_cast<T>(buf[k]);
        }
      }
      PetscFunctionReturn(0);
    };
    e.check = [this, &value, count, each, i = entries_.size() - 1] {
      const Entry& me = entries_[i];
      const int want = count ? count() : -1;
      if (me.given_flag && want >= 0 && static_cast<int>(value.size()) != want)
        bad(me.name, std::to_string(value.size()) + " values",
            std::to_string(want) + " comma-separated values");
      for (const T& v : value) each(v);
    };
    return *this;
  }

  std::string title_, prefix_;
  std::vector<Entry> entries_;
};

}  // namespace cellfsi
