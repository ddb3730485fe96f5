// Parameters described once (name, type, range, default, one-line help). CLI flags
// (--param name=value), JSON run records, viewer widgets and benchmark sweeps are generated from
// these descriptions.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

namespace softgi::render {

enum class ParamType { Int, Float, Bool, Enum };
const char* to_string(ParamType t);

struct ParamDesc {
  std::string name;
  ParamType type = ParamType::Float;
  std::string default_value;
  double min = 0.0, max = 0.0;           // Int and Float: inclusive range
  std::vector<std::string> choices;      // Enum
  std::string help;
  // Sweeps (ParamSet::sweep_values): Int/Float values span [min, max], log-spaced when set.
  bool sweep_log = false;
  // The quality ladder (softgi report): this parameter's value on each rung, from the cheapest
  // setting to the most accurate; empty when the ladder leaves it at its default. Every laddered
  // parameter of a technique has the same number of rungs (ParamSet checks it).
  std::vector<std::string> ladder;

  // This description with `values` as its ladder.
  ParamDesc with_ladder(std::vector<std::string> values) const;

  static ParamDesc integer(std::string name, int def, int lo, int hi, std::string help);
  static ParamDesc real(std::string name, double def, double lo, double hi, std::string help);
  static ParamDesc boolean(std::string name, bool def, std::string help);
  static ParamDesc choice(std::string name, std::string def, std::vector<std::string> choices, std::string help);
};

// Values of a set of described parameters. Every setter validates and throws std::invalid_argument
// with a message naming the parameter, the value and what was expected.
class ParamSet {
 public:
  ParamSet() = default;
  explicit ParamSet(std::vector<ParamDesc> descs);

  // "name=value"
  void set_assignment(const std::string& assignment);
  void set(const std::string& name, const std::string& value);

  int get_int(const std::string& name) const;
  double get_float(const std::string& name) const;
  bool get_bool(const std::string& name) const;
  const std::string& get_enum(const std::string& name) const;
  const std::string& get_text(const std::string& name) const;  // canonical text of any value

  const std::vector<ParamDesc>& descs() const { return descs_; }
  const ParamDesc& desc(const std::string& name) const;
  bool has(const std::string& name) const;
  // (name, canonical value) in description order: what run records store.
  std::vector<std::pair<std::string, std::string>> values() const;
  // `steps` values spanning the parameter's range (linear or log), or every choice of an Enum,
  // or {false, true}; canonical text, ready for set().
  std::vector<std::string> sweep_values(const std::string& name, int steps) const;
  // The quality ladder declared by the descriptions (ParamDesc::ladder): rung k assigns every laddered
  // parameter its k-th value (canonical text, ready for set()); the others keep their values. One
  // empty rung (the defaults) when no parameter is laddered.
  using Rung = std::vector<std::pair<std::string, std::string>>;
  std::vector<Rung> ladder() const;
  // One line per parameter: "name (type, range, default): help" for --help texts.
  std::string describe() const;

 private:
  std::vector<ParamDesc> descs_;
  std::map<std::string, std::string> values_;
  std::string canonical(const ParamDesc& d, const std::string& value) const;
};

}  // namespace softgi::render
