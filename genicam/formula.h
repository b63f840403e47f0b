// The availability and lock formulas of the register table
// (Feature::available_formula, locked_formula, EnumEntry::available_formula),
// parsed once and evaluated on register values: the device enforces the
// very formulas the XML gives clients (pIsAvailable, pIsLocked).
//
// The subset of GenICam's SwissKnife syntax they use: decimal integers,
// variables (a letter, then letters, digits or _), = and <> (GenICam's
// equal and not equal), < > <= >=, && ||, parentheses, spaces. Precedence
// as GenICam's (and Aravis's evaluator): || lowest, then &&, then = <>,
// then < > <= >=; each left to right. A comparison gives 1 or 0; && and ||
// take nonzero as true and give 1 or 0. (GenICam has no logical not: "!" is
// only part of C's "!=", which GenICam writes "<>".)
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "genicam/register_table.h"

namespace camsim::genicam {

class Formula {
 public:
  // Parses `text` over the variables `names` (variable i: names[i]); false
  // with *error saying what is wrong and at which character.
  bool Parse(const std::string& text, const std::vector<std::string>& names, std::string* error);
  // The value with variable i = values[i] (Parse must have succeeded).
  int64_t Evaluate(const std::vector<int64_t>& values) const;
  // The variables whose values decide Evaluate(values): of a true ||, its
  // first true operand's; of a false &&, its first false operand's; else
  // every operand's (in order, once each).
  std::vector<int> Deciding(const std::vector<int64_t>& values) const;
  // In words: variable i as name(i), a constant compared with variable i as
  // value(i, constant); = reads "is", <> "is not", && "and", || "or".
  std::string Describe(const std::function<std::string(int)>& name,
                       const std::function<std::string(int, int64_t)>& value) const;

 private:
  enum class Op : uint8_t { kConst, kVar, kEq, kNe, kLt, kGt, kLe, kGe, kAnd, kOr };
  struct Node {
    Op op;
    int64_t value;  // kConst: the constant; kVar: the variable's index
    int a, b;       // operands (nodes_ indices)
  };
  int64_t Eval(int node, const std::vector<int64_t>& values) const;
  void Decide(int node, const std::vector<int64_t>& values, std::vector<int>* out) const;
  std::string Words(int node, const std::function<std::string(int)>& name,
                    const std::function<std::string(int, int64_t)>& value) const;
  std::vector<Node> nodes_;
  int root_ = -1;
};

// An availability or lock rule of one register of FeatureRegisters: its
// formula parsed, its variables bound to registers.
struct RegisterRule {
  const Feature* feature = nullptr;   // the register whose value the rule guards
  const EnumEntry* entry = nullptr;   // non-null: the rule is this entry's (available while nonzero)
  bool lock = false;                  // locked while nonzero; else available while nonzero
  std::string text;                   // the formula as the table gives it
  Formula formula;
  // Per variable: its feature's register, and >= 0 when the variable is the
  // selector of a selected feature's register: that register's selection
  // (a client sees register i only while the selector is i).
  std::vector<const Feature*> variables;
  std::vector<int64_t> bound;
};

// The rules of `registers` (FeatureRegisters: the pointers point into it),
// aliases left out (their original's rule guards the register). False with
// *error naming the feature and what is wrong with its formula: one that
// does not parse, names a variable not in its `variables`, or a variable
// that names no integer, enumeration or Boolean register.
bool RegisterRules(const std::vector<Feature>& registers, std::vector<RegisterRule>* rules, std::string* error);
// The variables' values: `read` gives a register's 32 bits by address.
std::vector<int64_t> RuleValues(const RegisterRule& rule, const std::function<uint32_t(uint32_t)>& read);
// Whether the rule refuses a change of its register (or, for an entry, a
// change to it) at these values: locked, or not available.
bool RuleRefuses(const RegisterRule& rule, const std::vector<int64_t>& values);
// Why, in words: "locked: ExposureAuto is Once (locked while ExposureAuto
// is not Off or ExposureMode is TriggerWidth)", or "not available: ...
// (available while ...)"; an entry's says "entry NAME not available".
std::string RuleWhy(const RegisterRule& rule, const std::vector<int64_t>& values);

}  // namespace camsim::genicam
