// OptionTable (common/option_table.hpp): defaults kept, values read, and each kind of bad input refused with
// one message naming the option.
#include <gtest/gtest.h>
#include <petscsys.h>

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "common/option_table.hpp"

using cellfsi::OptionTable;

namespace {

/// Sets options for one test and clears them afterwards.
class OptionTableTest : public ::testing::Test {
 protected:
  void TearDown() override { PetscOptionsClear(nullptr); }
  static void set(const char* name, const char* value) { PetscOptionsSetValue(nullptr, name, value); }
  /// The message of the std::invalid_argument that f throws ("" if none).
  template <class F>
  static std::string error_of(F&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  }
};

struct Settings {
  double dt = 5e-4;
  int every = 0;
  bool restart = false;
  std::string flow = "shear";
  std::vector<double> size{0.0024, 0.0012};
  std::vector<int> elements{64, 32};
  std::vector<std::string> bodies;
  int dim = 2;
};

void declare(OptionTable& t, Settings& s) {
  t.integer("dim", s.dim, "Dimension", cellfsi::int_between(2, 3))
      .real("dt", s.dt, "Time step [s]", cellfsi::positive("[s]"))
      .integer("every", s.every, "Every N steps", cellfsi::at_least(0, "(0: never)"))
      .flag("restart", s.restart, "Restart")
      .text("flow", s.flow, "Flow", {"shear", "poiseuille", "rest"})
      .reals(
          "size", s.size, "Extent", [&s] { return s.dim; }, cellfsi::positive("[cm]"))
      .integers(
          "elements", s.elements, "Elements", [&s] { return s.dim; }, cellfsi::at_least(1))
      .texts("bodies", s.bodies, "Bodies", 3);
}

}  // namespace

TEST_F(OptionTableTest, KeepsDefaultsAndReadsGivenValues) {
  Settings s;
  OptionTable t("test", "t_");
  declare(t, s);
  set("-t_dt", "1e-3");
  set("-t_flow", "poiseuille");
  set("-t_dim", "3");
  set("-t_size", "1,2,3");
  set("-t_restart", nullptr);
  set("-t_bodies", "a,b");
  t.read();
  EXPECT_DOUBLE_EQ(s.dt, 1e-3);
  EXPECT_EQ(s.every, 0);  // default kept
  EXPECT_TRUE(s.restart);
  EXPECT_EQ(s.flow, "poiseuille");
  EXPECT_EQ(s.size, (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(s.elements, (std::vector<int>{64, 32}));  // default kept (its length is not checked)
  EXPECT_EQ(s.bodies, (std::vector<std::string>{"a", "b"}));
  EXPECT_TRUE(t.given("dt"));
  EXPECT_FALSE(t.given("every"));
}

TEST_F(OptionTableTest, RefusesEachKindOfBadInputNamingTheOption) {
  const std::vector<std::pair<std::vector<std::pair<const char*, const char*>>, std::string>> cases = {
      {{{"-t_dt", "-1"}}, "option -t_dt = -1 is invalid; valid: > 0 [s]"},
      {{{"-t_dt", "abc"}}, "option -t_dt = abc is invalid; valid: a number"},
      {{{"-t_dt", nullptr}}, "option -t_dt has no value; valid: a number"},
      {{{"-t_every", "-2"}}, "option -t_every = -2 is invalid; valid: >= 0 (0: never)"},
      {{{"-t_every", "10000000000"}}, "option -t_every = 10000000000 is invalid; valid: an integer up to"},
      {{{"-t_dim", "4"}}, "option -t_dim = 4 is invalid; valid: 2 ... 3"},
      {{{"-t_flow", "couette"}}, "option -t_flow = couette is invalid; valid: shear, poiseuille or rest"},
      {{{"-t_size", "1,2,3"}}, "option -t_size = 3 values is invalid; valid: 2 comma-separated values"},
      {{{"-t_size", "1,-2"}}, "option -t_size = -2 is invalid; valid: > 0 [cm]"},
      {{{"-t_elements", "4,0"}}, "option -t_elements = 0 is invalid; valid: >= 1"},
      {{{"-t_bodies", "a,b,c,d"}}, "option -t_bodies = 4 values is invalid; valid: at most 3"},
  };
  for (const auto& [options, message] : cases) {
    PetscOptionsClear(nullptr);
    for (const auto& [name, value] : options) set(name, value);
    Settings s;
    OptionTable t("test", "t_");
    declare(t, s);
    const std::string what = error_of([&] { t.read(); });
    EXPECT_EQ(what.substr(0, message.size()), message) << options.front().first << ": " << what;
  }
}

TEST_F(OptionTableTest, BadReportsTheFullName) {
  Settings s;
  OptionTable t("test", "t_");
  declare(t, s);
  t.read();
  EXPECT_EQ(error_of([&] { t.bad("size", "(given)", "not with -domain narrowing"); }),
            "option -t_size = (given) is invalid; valid: not with -domain narrowing");
}

TEST_F(OptionTableTest, HelpStatesEachRangeAsTheCheckNamesIt) {
  // -help lists each option with "[valid: ...]" where the table states a range or choices, the same words the
  // check names when it refuses a value (scripts/options-doc.py reads them from -help instead of probing).
  set("-help", nullptr);
  Settings s;
  OptionTable t("help test", "h_");
  declare(t, s);
  ::testing::internal::CaptureStdout();
  t.read();
  std::fflush(stdout);
  const std::string help = ::testing::internal::GetCapturedStdout();
  auto line_of = [&help](const std::string& option) {
    std::size_t at = help.find("  -h_" + option + " ");  // "-NAME <default>: help"
    if (at == std::string::npos) at = help.find("  -h_" + option + ":");  // a flag: "-NAME: <...> help"
    return at == std::string::npos ? std::string() : help.substr(at, help.find('\n', at) - at);
  };
  const std::vector<std::pair<std::string, std::string>> stated = {{"dim", "2 ... 3"},
                                                                   {"dt", "> 0 [s]"},
                                                                   {"every", ">= 0 (0: never)"},
                                                                   {"flow", "shear, poiseuille or rest"},
                                                                   {"size", "> 0 [cm]"},
                                                                   {"elements", ">= 1"}};
  for (const auto& [option, valid] : stated) {
    EXPECT_NE(line_of(option).find(" [valid: " + valid + "]"), std::string::npos) << line_of(option);
    // The check, given a value outside the range, names the same words.
    PetscOptionsClear(nullptr);
    set(("-h_" + option).c_str(), option == "flow"   ? "sideways"
                                   : option == "size" ? "-1,1"
                                   : option == "elements" ? "-1,4"
                                                          : "-1");
    Settings fresh;
    OptionTable u("check", "h_");
    declare(u, fresh);
    const std::string what = error_of([&] { u.read(); });
    EXPECT_TRUE(what.ends_with("; valid: " + valid)) << option << ": " << what;
  }
  for (const char* option : {"restart", "bodies"}) {  // no range: nothing stated
    EXPECT_FALSE(line_of(option).empty()) << option;
    EXPECT_EQ(line_of(option).find("[valid:"), std::string::npos) << line_of(option);
  }
}
