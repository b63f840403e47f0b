// The availability and lock formulas' evaluator (genicam/formula.h): its
// values against Aravis's own evaluator (what clients compute from the XML),
// its parse errors, its words, and the table's rules.
#include <arv.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "genicam/formula.h"
#include "genicam/register_table.h"

namespace camsim {
namespace {

using genicam::Formula;

genicam::SensorInfo FullSensor() {
  genicam::SensorInfo s;
  s.width = 64;
  s.height = 48;
  s.has_isp_rgb = true;
  s.has_white_balance = true;
  s.has_gamma = true;
  s.has_trigger_line = true;
  s.stage_names = {"exposure", "cfa", "sensor", "gamma"};
  return s;
}

// Aravis's value of `text` with variable names[i] = values[i].
int64_t AravisValue(const std::string& text, const std::vector<std::string>& names,
                    const std::vector<int64_t>& values) {
  ArvEvaluator* e = arv_evaluator_new(text.c_str());
  for (size_t i = 0; i < names.size(); ++i) arv_evaluator_set_int64_variable(e, names[i].c_str(), values[i]);
  GError* error = nullptr;
  const int64_t v = arv_evaluator_evaluate_as_int64(e, &error);
  EXPECT_EQ(error, nullptr) << text << ": " << (error ? error->message : "");
  g_clear_error(&error);
  g_object_unref(e);
  return v;
}

// Every assignment of 0..top to the variables, through f(values).
template <typename F>
void EachAssignment(size_t n, int64_t top, F f) {
  std::vector<int64_t> values(n, 0);
  for (;;) {
    f(values);
    size_t i = 0;
    while (i < n && values[i] == top) values[i++] = 0;
    if (i == n) return;
    ++values[i];
  }
}

// Precedence, associativity and spaces as Aravis evaluates them, on every
// assignment of 0..2 to the variables.
TEST(GigeFormula, EvaluatesAsAravisDoes) {
  const std::vector<std::string> names = {"A", "B", "C"};
  for (const char* text :
       {"A=1", "A<>1", "A<B", "A>B", "A<=B", "A>=B", "A=1||B=1&&C=1", "(A=1||B=1)&&C=1", "A=B=C", "A<B=C<A",
        "A<>B<>C", "A||B&&C", "A&&B||C", "(A=0)&&(B<>2)||(C>=1)", " ( A = 1 ) && ( B <> 0 ) ", "2", "A",
        "((A))", "A=1&&B=1&&C=1", "A=1||B=1||C=1", "0<A&&A<2"}) {
    Formula f;
    std::string error;
    ASSERT_TRUE(f.Parse(text, names, &error)) << text << ": " << error;
    EachAssignment(names.size(), 2, [&](const std::vector<int64_t>& v) {
      EXPECT_EQ(f.Evaluate(v), AravisValue(text, names, v))
          << text << " at A=" << v[0] << " B=" << v[1] << " C=" << v[2];
    });
  }
}

// The table's own formulas, as the XML gives them to clients.
TEST(GigeFormula, TheTablesFormulasEvaluateAsAravisDoes) {
  int checked = 0;
  const auto check = [&](const std::string& text, const std::vector<std::pair<std::string, std::string>>& vars) {
    std::vector<std::string> names;
    for (const auto& v : vars) names.push_back(v.first);
    Formula f;
    std::string error;
    ASSERT_TRUE(f.Parse(text, names, &error)) << text << ": " << error;
    EachAssignment(names.size(), 3, [&](const std::vector<int64_t>& v) {
      EXPECT_EQ(f.Evaluate(v), AravisValue(text, names, v)) << text;
    });
    ++checked;
  };
  for (const genicam::Feature& f : genicam::RegisterTable(FullSensor())) {
    if (!f.available_formula.empty()) check(f.available_formula, f.variables);
    if (!f.locked_formula.empty()) check(f.locked_formula, f.variables);
    for (const genicam::EnumEntry& e : f.entries)
      if (!e.available_formula.empty()) check(e.available_formula, e.variables);
  }
  EXPECT_GE(checked, 12);
}

TEST(GigeFormula, ParseErrorsSayWhatAndWhere) {
  const std::vector<std::string> names = {"A", "B"};
  const struct {
    const char* text;
    const char* error;
  } cases[] = {
      {"", "empty formula"},
      {"   ", "empty formula"},
      {"A=", "at character 3: expected a number, a variable or '(', found the end"},
      {"(A=1", "at character 5: expected ')'"},
      {"A=1)", "at character 4: ')' without its '('"},
      {"X=1", "at character 1: unknown variable 'X'"},
      {"A=1&&Bee=2", "at character 6: unknown variable 'Bee'"},
      {"A!=1", "at character 2: '!' is not GenICam"},
      {"!A", "at character 1: '!' is not GenICam"},
      {"A==1", "at character 2: '==' is not GenICam: equal is '='"},
      {"A=1 B=1", "at character 5: unexpected 'B'"},
      {"A+1", "at character 2: unexpected '+'"},
      {"A=99999999999999999999", "number out of range"},
      {"A=&&B", "at character 3: expected a number, a variable or '(', found '&'"},
      {"()", "at character 2: expected a number, a variable or '(', found ')'"},
  };
  for (const auto& c : cases) {
    Formula f;
    std::string error;
    EXPECT_FALSE(f.Parse(c.text, names, &error)) << c.text;
    EXPECT_NE(error.find(c.error), std::string::npos) << c.text << ": " << error;
  }
}

// The table's rules on its registers: every formula parses and names
// registers; a bad one is a configuration error naming the feature.
TEST(GigeFormula, TheTablesRulesBuildAndABadOneIsNamed) {
  const auto table = genicam::RegisterTable(FullSensor());
  const auto registers = genicam::FeatureRegisters(table);
  std::vector<genicam::RegisterRule> rules;
  std::string error;
  ASSERT_TRUE(genicam::RegisterRules(registers, &rules, &error)) << error;
  std::vector<std::string> names;
  for (const auto& r : rules) names.push_back(r.feature->name + (r.entry ? "." + r.entry->name : ""));
  EXPECT_EQ(names, (std::vector<std::string>{"ExposureMode.TriggerWidth", "ExposureTime", "ExposureAuto",
                                              "TriggerMode", "TriggerSource", "TriggerActivation", "TriggerSoftware",
                                              "Gain", "GainRaw", "Gamma", "LineInverter[0]", "LineInverter[1]",
                                              "LineDebouncerTime", "UserSetSave"}));
  // LineInverter[1]'s LineSelector is its selection: never locked.
  for (const auto& r : rules)
    if (r.feature->name == "LineInverter[1]") {
      EXPECT_EQ(r.bound, (std::vector<int64_t>{-1, 1}));
      EXPECT_FALSE(genicam::RuleRefuses(r, genicam::RuleValues(r, [](uint32_t) { return 1u; })));
    }

  auto bad = registers;
  for (auto& f : bad)
    if (f.name == "ExposureTime") f.locked_formula = "(A<>0)||(E=";
  EXPECT_FALSE(genicam::RegisterRules(bad, &rules, &error));
  EXPECT_NE(error.find("feature ExposureTime, locked formula '(A<>0)||(E=': at character 12"), std::string::npos)
      << error;
  bad = registers;
  for (auto& f : bad)
    if (f.name == "LineDebouncerTime") f.available_formula = "L=0&&X=0";
  EXPECT_FALSE(genicam::RegisterRules(bad, &rules, &error));
  EXPECT_NE(error.find("feature LineDebouncerTime, available formula 'L=0&&X=0': at character 6: unknown variable 'X'"),
            std::string::npos)
      << error;
  bad = registers;
  for (auto& f : bad)
    if (f.name == "LineDebouncerTime") f.variables = {{"L", "BlackLevel"}};
  EXPECT_FALSE(genicam::RegisterRules(bad, &rules, &error));
  EXPECT_NE(error.find("variable L names 'BlackLevel', not an integer, enumeration or Boolean register"),
            std::string::npos)
      << error;
}

// The refusal's words: the variables that decide, by name and value, and the rule.
TEST(GigeFormula, RulesSayWhyInWords) {
  const auto registers = genicam::FeatureRegisters(genicam::RegisterTable(FullSensor()));
  std::vector<genicam::RegisterRule> rules;
  std::string error;
  ASSERT_TRUE(genicam::RegisterRules(registers, &rules, &error)) << error;
  const auto rule = [&](const std::string& name) -> const genicam::RegisterRule& {
    for (const auto& r : rules)
      if (r.feature->name + (r.entry ? "." + r.entry->name : "") == name) return r;
    ADD_FAILURE() << name;
    return rules[0];
  };
  const auto& exposure = rule("ExposureTime");  // variables A (ExposureAuto), E (ExposureMode)
  EXPECT_FALSE(genicam::RuleRefuses(exposure, {genicam::kAutoOff, genicam::kExposureTimed}));
  EXPECT_TRUE(genicam::RuleRefuses(exposure, {genicam::kAutoOnce, genicam::kExposureTimed}));
  EXPECT_EQ(genicam::RuleWhy(exposure, {genicam::kAutoOnce, genicam::kExposureTimed}),
            "locked: ExposureAuto is Once (locked while ExposureAuto is not Off or ExposureMode is TriggerWidth)");
  EXPECT_EQ(genicam::RuleWhy(exposure, {genicam::kAutoOff, genicam::kExposureTriggerWidth}),
            "locked: ExposureMode is TriggerWidth (locked while ExposureAuto is not Off or ExposureMode is "
            "TriggerWidth)");
  const auto& width = rule("ExposureMode.TriggerWidth");  // M, S, A
  EXPECT_EQ(genicam::RuleWhy(width, {0, genicam::kSourceLine0, genicam::kAutoOff}),
            "entry TriggerWidth not available: TriggerMode is Off (available while TriggerMode is On and "
            "TriggerSource is Line0 and ExposureAuto is Off)");
  EXPECT_FALSE(genicam::RuleRefuses(width, {1, genicam::kSourceLine0, genicam::kAutoOff}));
  EXPECT_EQ(genicam::RuleWhy(rule("Gamma"), {0}), "not available: GammaEnable is false (available while GammaEnable "
                                                  "is true)");
  EXPECT_EQ(genicam::RuleWhy(rule("LineDebouncerTime"), {1}),
            "not available: LineSelector is Line1 (available while LineSelector is Line0)");
  EXPECT_EQ(genicam::RuleWhy(rule("UserSetSave"), {0}),
            "not available: UserSetSelector is Default (available while UserSetSelector is not Default)");
}

}  // namespace
}  // namespace camsim
