#include "genicam/formula.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <limits>
#include <string>

namespace camsim::genicam {

namespace {

constexpr char kNoNot[] = "'!' is not GenICam (not equal is '<>'; there is no logical not)";

// The text being parsed: where the parse is, and its first error.
struct Parser {
  explicit Parser(const std::string& text) : text_(text) {}
  std::string error_;
  size_t at_ = 0;
  const std::string& text_;

  void Space() {
    while (at_ < text_.size() && text_[at_] == ' ') ++at_;
  }
  bool Take(const char* s) {
    Space();
    const size_t n = std::char_traits<char>::length(s);
    if (text_.compare(at_, n, s) != 0) return false;
    at_ += n;
    return true;
  }
  // -1 (no node), with the first error kept.
  int Fail(const std::string& what) {
    if (error_.empty()) error_ = "at character " + std::to_string(at_ + 1) + ": " + what;
    return -1;
  }
};

}  // namespace

bool Formula::Parse(const std::string& text, const std::vector<std::string>& names, std::string* error) {
  nodes_.clear();
  root_ = -1;
  Parser p(text);
  const auto add = [this](Op op, int64_t value, int a, int b) {
    nodes_.push_back({op, value, a, b});
    return static_cast<int>(nodes_.size()) - 1;
  };
  // Recursive descent, one level per precedence (formula.h), lowest first:
  // each level's operands one level down, left to right. The operator at the
  // cursor is read whole (the longest that matches), so "<>" is never "<".
  static const std::vector<std::vector<std::pair<std::string, Op>>> kLevels = {
      {{"||", Op::kOr}},
      {{"&&", Op::kAnd}},
      {{"=", Op::kEq}, {"<>", Op::kNe}},
      {{"<", Op::kLt}, {">", Op::kGt}, {"<=", Op::kLe}, {">=", Op::kGe}}};
  const auto operator_here = [&]() -> std::string {
    p.Space();
    for (const char* op : {"||", "&&", "<>", "<=", ">=", "==", "=", "<", ">"})
      if (text.compare(p.at_, std::strlen(op), op) == 0) return op;
    return "";
  };
  std::function<int(size_t)> level;
  const auto primary = [&]() -> int {
    p.Space();
    if (p.at_ >= text.size()) return p.Fail("expected a number, a variable or '(', found the end");
    const char c = text[p.at_];
    if (c == '(') {
      ++p.at_;
      const int inner = level(0);
      if (inner < 0) return -1;
      if (!p.Take(")")) return p.Fail("expected ')'");
      return inner;
    }
    if (std::isdigit(static_cast<unsigned char>(c))) {
      int64_t v = 0;
      while (p.at_ < text.size() && std::isdigit(static_cast<unsigned char>(text[p.at_]))) {
        const int digit = text[p.at_] - '0';
        if (v > (std::numeric_limits<int64_t>::max() - digit) / 10) return p.Fail("number out of range");
        v = v * 10 + digit;
        ++p.at_;
      }
      return add(Op::kConst, v, -1, -1);
    }
    if (std::isalpha(static_cast<unsigned char>(c))) {
      const size_t start = p.at_;
      while (p.at_ < text.size() && (std::isalnum(static_cast<unsigned char>(text[p.at_])) || text[p.at_] == '_'))
        ++p.at_;
      const std::string name = text.substr(start, p.at_ - start);
      const auto it = std::find(names.begin(), names.end(), name);
      if (it == names.end()) {
        p.at_ = start;
        return p.Fail("unknown variable '" + name + "'");
      }
      return add(Op::kVar, it - names.begin(), -1, -1);
    }
    if (c == '!') return p.Fail(kNoNot);
    return p.Fail(std::string("expected a number, a variable or '(', found '") + c + "'");
  };
  level = [&](size_t l) -> int {
    if (l == kLevels.size()) return primary();
    int left = level(l + 1);
    while (left >= 0) {
      const std::string op = operator_here();
      if (op == "==") return p.Fail("'==' is not GenICam: equal is '='");
      const auto it = std::find_if(kLevels[l].begin(), kLevels[l].end(), [&](const auto& o) { return o.first == op; });
      if (it == kLevels[l].end()) break;
      p.at_ += op.size();
      const int right = level(l + 1);
      if (right < 0) return -1;
      left = add(it->second, 0, left, right);
    }
    return left;
  };
  p.Space();
  if (text.empty() || p.at_ == text.size()) {
    *error = "empty formula";
    return false;
  }
  const int root = level(0);
  p.Space();
  if (root >= 0 && p.at_ != text.size()) {
    if (text[p.at_] == ')') p.Fail("')' without its '('");
    else if (text[p.at_] == '!') p.Fail(kNoNot);
    else p.Fail(std::string("unexpected '") + text[p.at_] + "' (this subset has = <> < > <= >= && || and parentheses)");
  }
  if (!p.error_.empty()) {
    *error = p.error_;
    nodes_.clear();
    return false;
  }
  root_ = root;
  return true;
}

int64_t Formula::Evaluate(const std::vector<int64_t>& values) const { return Eval(root_, values); }

int64_t Formula::Eval(int i, const std::vector<int64_t>& values) const {
  const Node& n = nodes_[static_cast<size_t>(i)];
  switch (n.op) {
    case Op::kConst: return n.value;
    case Op::kVar: return values[static_cast<size_t>(n.value)];
    case Op::kAnd: return Eval(n.a, values) != 0 && Eval(n.b, values) != 0;
    case Op::kOr: return Eval(n.a, values) != 0 || Eval(n.b, values) != 0;
    default: break;
  }
  const int64_t a = Eval(n.a, values), b = Eval(n.b, values);
  switch (n.op) {
    case Op::kEq: return a == b;
    case Op::kNe: return a != b;
    case Op::kLt: return a < b;
    case Op::kGt: return a > b;
    case Op::kLe: return a <= b;
    case Op::kGe: return a >= b;
    default: return 0;
  }
}

std::vector<int> Formula::Deciding(const std::vector<int64_t>& values) const {
  std::vector<int> out;
  Decide(root_, values, &out);
  return out;
}

void Formula::Decide(int i, const std::vector<int64_t>& values, std::vector<int>* out) const {
  const Node& n = nodes_[static_cast<size_t>(i)];
  switch (n.op) {
    case Op::kConst: return;
    case Op::kVar:
      if (std::find(out->begin(), out->end(), n.value) == out->end()) out->push_back(static_cast<int>(n.value));
      return;
    case Op::kAnd:
    case Op::kOr: {
      // The operand that alone decides: a false one of &&, a true one of ||.
      const bool decisive = n.op == Op::kOr;
      if ((Eval(i, values) != 0) == decisive)
        for (const int operand : {n.a, n.b})
          if ((Eval(operand, values) != 0) == decisive) return Decide(operand, values, out);
      break;
    }
    default: break;
  }
  Decide(n.a, values, out);
  Decide(n.b, values, out);
}

std::string Formula::Describe(const std::function<std::string(int)>& name,
                              const std::function<std::string(int, int64_t)>& value) const {
  return Words(root_, name, value);
}

std::string Formula::Words(int i, const std::function<std::string(int)>& name,
                           const std::function<std::string(int, int64_t)>& value) const {
  const Node& n = nodes_[static_cast<size_t>(i)];
  switch (n.op) {
    case Op::kConst: return std::to_string(n.value);
    case Op::kVar: return name(static_cast<int>(n.value));
    case Op::kAnd:
    case Op::kOr: {
      // An || inside an && keeps its parentheses.
      const auto operand = [&](int o) {
        const std::string w = Words(o, name, value);
        return n.op == Op::kAnd && nodes_[static_cast<size_t>(o)].op == Op::kOr ? "(" + w + ")" : w;
      };
      return operand(n.a) + (n.op == Op::kAnd ? " and " : " or ") + operand(n.b);
    }
    default: break;
  }
  const Node& a = nodes_[static_cast<size_t>(n.a)];
  const Node& b = nodes_[static_cast<size_t>(n.b)];
  // A constant compared with a variable: by the variable's name for it.
  const auto side = [&](const Node& x, const Node& other, int index) {
    if (x.op == Op::kConst && other.op == Op::kVar) return value(static_cast<int>(other.value), x.value);
    const std::string w = Words(index, name, value);
    return x.op == Op::kAnd || x.op == Op::kOr ? "(" + w + ")" : w;
  };
  const char* op = n.op == Op::kEq ? " is " : n.op == Op::kNe ? " is not " : n.op == Op::kLt ? " < "
                   : n.op == Op::kGt ? " > " : n.op == Op::kLe ? " <= " : " >= ";
  return side(a, b, n.a) + op + side(b, a, n.b);
}

bool RegisterRules(const std::vector<Feature>& registers, std::vector<RegisterRule>* rules, std::string* error) {
  rules->clear();
  // One rule: its formula over the feature's (or entry's) variables.
  const auto add = [&](const Feature& f, const EnumEntry* entry, bool lock, const std::string& text,
                       const std::vector<std::pair<std::string, std::string>>& variables) {
    RegisterRule r;
    r.feature = &f;
    r.entry = entry;
    r.lock = lock;
    r.text = text;
    const std::string where = "feature " + f.name + (entry ? " entry " + entry->name : "") + ", " +
                              (lock ? "locked" : "available") + " formula '" + text + "': ";
    std::vector<std::string> names;
    for (const auto& [variable, feature] : variables) {
      names.push_back(variable);
      // The register's own selector: fixed at its selection.
      const bool own_selector = f.selection >= 0 && feature == f.selected_by;
      const Feature* v = FindFeature(registers, feature);
      if (v == nullptr || !v->alias_of.empty() || v->length != 4 ||
          (v->kind != Kind::kInteger && v->kind != Kind::kEnum && v->kind != Kind::kBoolean)) {
        *error = where + "variable " + variable + " names '" + feature +
                 "', not an integer, enumeration or Boolean register";
        return false;
      }
      r.variables.push_back(v);
      r.bound.push_back(own_selector ? f.selection : -1);
    }
    std::string why;
    if (!r.formula.Parse(text, names, &why)) {
      *error = where + why;
      return false;
    }
    rules->push_back(std::move(r));
    return true;
  };
  for (const Feature& f : registers) {
    if (!f.alias_of.empty()) continue;
    if (!f.available_formula.empty() && !add(f, nullptr, false, f.available_formula, f.variables)) return false;
    if (!f.locked_formula.empty() && !add(f, nullptr, true, f.locked_formula, f.variables)) return false;
    for (const EnumEntry& e : f.entries)
      if (!e.available_formula.empty() && !add(f, &e, false, e.available_formula, e.variables)) return false;
  }
  return true;
}

std::vector<int64_t> RuleValues(const RegisterRule& rule, const std::function<uint32_t(uint32_t)>& read) {
  std::vector<int64_t> values;
  for (size_t i = 0; i < rule.variables.size(); ++i) {
    const Feature& v = *rule.variables[i];
    const uint32_t bits = read(v.address);
    const uint32_t masked = v.low_bits > 0 ? (bits >> v.shift) & ((uint32_t{1} << v.low_bits) - 1) : bits;
    values.push_back(rule.bound[i] >= 0 ? rule.bound[i] : int64_t{masked});
  }
  return values;
}

bool RuleRefuses(const RegisterRule& rule, const std::vector<int64_t>& values) {
  return (rule.formula.Evaluate(values) != 0) == rule.lock;
}

std::string RuleWhy(const RegisterRule& rule, const std::vector<int64_t>& values) {
  const auto name = [&](int i) {
    const Feature& v = *rule.variables[static_cast<size_t>(i)];
    return v.name.substr(0, v.name.find('['));
  };
  const auto value = [&](int i, int64_t x) {
    const Feature& v = *rule.variables[static_cast<size_t>(i)];
    if (v.kind == Kind::kBoolean && (x == 0 || x == 1)) return std::string(x ? "true" : "false");
    for (const EnumEntry& e : v.entries)
      if (e.value == x) return e.name;
    return std::to_string(x);
  };
  std::string now;
  for (const int i : rule.formula.Deciding(values))
    now += (now.empty() ? "" : ", ") + name(i) + " is " + value(i, values[static_cast<size_t>(i)]);
  const std::string state = rule.lock ? "locked" : "available";
  return (rule.entry ? "entry " + rule.entry->name + " " : std::string()) + (rule.lock ? "locked: " : "not available: ") +
         now + " (" + state + " while " + rule.formula.Describe(name, value) + ")";
}

}  // namespace camsim::genicam
