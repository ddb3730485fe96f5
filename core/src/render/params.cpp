#include "softgi/render/params.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace softgi::render {

const char* to_string(ParamType t) {
  switch (t) {
    case ParamType::Int: return "int";
    case ParamType::Float: return "float";
    case ParamType::Bool: return "bool";
    case ParamType::Enum: return "enum";
  }
  return "?";
}

ParamDesc ParamDesc::integer(std::string name, int def, int lo, int hi, std::string help) {
  ParamDesc d;
  d.name = std::move(name);
  d.type = ParamType::Int;
  d.default_value = std::to_string(def);
  d.min = lo;
  d.max = hi;
  d.help = std::move(help);
  return d;
}
ParamDesc ParamDesc::real(std::string name, double def, double lo, double hi, std::string help) {
  ParamDesc d;
  d.name = std::move(name);
  d.type = ParamType::Float;
  std::ostringstream os;
  os << def;
  d.default_value = os.str();
  d.min = lo;
  d.max = hi;
  d.help = std::move(help);
  return d;
}
ParamDesc ParamDesc::boolean(std::string name, bool def, std::string help) {
  ParamDesc d;
  d.name = std::move(name);
  d.type = ParamType::Bool;
  d.default_value = def ? "true" : "false";
  d.help = std::move(help);
  return d;
}
ParamDesc ParamDesc::choice(std::string name, std::string def, std::vector<std::string> choices, std::string help) {
  ParamDesc d;
  d.name = std::move(name);
  d.type = ParamType::Enum;
  d.default_value = std::move(def);
  d.choices = std::move(choices);
  d.help = std::move(help);
  return d;
}

namespace {
std::string range_text(const ParamDesc& d) {
  std::ostringstream os;
  switch (d.type) {
    case ParamType::Int: os << "[" << static_cast<long long>(d.min) << ", " << static_cast<long long>(d.max) << "]"; break;
    case ParamType::Float: os << "[" << d.min << ", " << d.max << "]"; break;
    case ParamType::Bool: os << "true|false"; break;
    case ParamType::Enum:
      for (std::size_t i = 0; i < d.choices.size(); ++i) os << (i ? "|" : "") << d.choices[i];
      break;
  }
  return os.str();
}
[[noreturn]] void bad_value(const ParamDesc& d, const std::string& value, const std::string& why) {
  throw std::invalid_argument("parameter '" + d.name + "': " + why + " '" + value + "' (expected " +
                              to_string(d.type) + " in " + range_text(d) + ")");
}
}  // namespace

ParamDesc ParamDesc::with_ladder(std::vector<std::string> values) const {
  ParamDesc d = *this;
  d.ladder = std::move(values);
  return d;
}

ParamSet::ParamSet(std::vector<ParamDesc> descs) : descs_(std::move(descs)) {
  for (const auto& d : descs_) {
    if (values_.count(d.name)) throw std::logic_error("parameter '" + d.name + "' described twice");
    values_[d.name] = canonical(d, d.default_value);  // defaults must satisfy their own description
  }
  // A ladder is part of the description: a bad one is the technique's bug, found as soon as its
  // parameters are first made rather than in the middle of a report.
  std::size_t rungs = 0;
  std::string first;
  for (auto& d : descs_) {
    if (d.ladder.empty()) continue;
    for (auto& v : d.ladder) {
      try {
        v = canonical(d, v);
      } catch (const std::invalid_argument& e) {
        throw std::logic_error("quality ladder of '" + d.name + "': " + e.what());
      }
    }
    if (rungs == 0) {
      rungs = d.ladder.size();
      first = d.name;
    } else if (d.ladder.size() != rungs) {
      throw std::logic_error("quality ladder: '" + d.name + "' has " + std::to_string(d.ladder.size()) + " rungs, '" + first +
                             "' has " + std::to_string(rungs));
    }
  }
}

std::vector<ParamSet::Rung> ParamSet::ladder() const {
  std::size_t rungs = 0;
  for (const auto& d : descs_) rungs = std::max(rungs, d.ladder.size());
  if (rungs == 0) return {Rung{}};
  std::vector<Rung> out(rungs);
  for (const auto& d : descs_)
    for (std::size_t k = 0; k < d.ladder.size(); ++k) out[k].emplace_back(d.name, d.ladder[k]);
  return out;
}

std::string ParamSet::canonical(const ParamDesc& d, const std::string& value) const {
  switch (d.type) {
    case ParamType::Int: {
      long long v = 0;
      auto [p, ec] = std::from_chars(value.data(), value.data() + value.size(), v);
      if (ec != std::errc() || p != value.data() + value.size()) bad_value(d, value, "not an integer:");
      if (v < d.min || v > d.max) bad_value(d, value, "out of range:");
      return std::to_string(v);
    }
    case ParamType::Float: {
      double v = 0;
      std::size_t used = 0;
      try {
        v = std::stod(value, &used);
      } catch (const std::exception&) {
        bad_value(d, value, "not a number:");
      }
      if (used != value.size()) bad_value(d, value, "not a number:");
      if (!std::isfinite(v)) bad_value(d, value, "not finite:");
      if (v < d.min || v > d.max) bad_value(d, value, "out of range:");
      std::ostringstream os;
      os.precision(17);
      os << v;
      return os.str();
    }
    case ParamType::Bool:
      if (value == "true" || value == "1" || value == "on" || value == "yes") return "true";
      if (value == "false" || value == "0" || value == "off" || value == "no") return "false";
      bad_value(d, value, "not a boolean:");
    case ParamType::Enum: {
      for (const auto& c : d.choices)
        if (c == value) return c;
      bad_value(d, value, "unknown choice");
    }
  }
  bad_value(d, value, "unsupported");
}

const ParamDesc& ParamSet::desc(const std::string& name) const {
  for (const auto& d : descs_)
    if (d.name == name) return d;
  std::string known;
  for (const auto& d : descs_) known += (known.empty() ? "" : ", ") + d.name;
  throw std::invalid_argument("unknown parameter '" + name + "' (known: " + (known.empty() ? "none" : known) + ")");
}

bool ParamSet::has(const std::string& name) const { return values_.count(name) != 0; }

void ParamSet::set(const std::string& name, const std::string& value) { values_[name] = canonical(desc(name), value); }

void ParamSet::set_assignment(const std::string& assignment) {
  auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw std::invalid_argument("parameter assignment '" + assignment + "' is not of the form name=value");
  set(assignment.substr(0, eq), assignment.substr(eq + 1));
}

const std::string& ParamSet::get_text(const std::string& name) const {
  desc(name);
  return values_.at(name);
}
int ParamSet::get_int(const std::string& name) const {
  if (desc(name).type != ParamType::Int) throw std::logic_error("parameter '" + name + "' is not an int");
  return std::stoi(values_.at(name));
}
double ParamSet::get_float(const std::string& name) const {
  auto t = desc(name).type;
  if (t != ParamType::Float && t != ParamType::Int) throw std::logic_error("parameter '" + name + "' is not numeric");
  return std::stod(values_.at(name));
}
bool ParamSet::get_bool(const std::string& name) const {
  if (desc(name).type != ParamType::Bool) throw std::logic_error("parameter '" + name + "' is not a bool");
  return values_.at(name) == "true";
}
const std::string& ParamSet::get_enum(const std::string& name) const {
  if (desc(name).type != ParamType::Enum) throw std::logic_error("parameter '" + name + "' is not an enum");
  return values_.at(name);
}

std::vector<std::pair<std::string, std::string>> ParamSet::values() const {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& d : descs_) out.emplace_back(d.name, values_.at(d.name));
  return out;
}

std::vector<std::string> ParamSet::sweep_values(const std::string& name, int steps) const {
  const ParamDesc& d = desc(name);
  std::vector<std::string> out;
  if (d.type == ParamType::Enum) return d.choices;
  if (d.type == ParamType::Bool) return {"false", "true"};
  if (steps < 1) throw std::invalid_argument("sweep of '" + name + "' needs at least one step");
  for (int i = 0; i < steps; ++i) {
    double t = steps == 1 ? 0.0 : double(i) / (steps - 1);
    double v = d.sweep_log && d.min > 0 ? d.min * std::pow(d.max / d.min, t) : d.min + t * (d.max - d.min);
    std::string text;
    if (d.type == ParamType::Int) {
      text = std::to_string(static_cast<long long>(std::llround(v)));
    } else {
      std::ostringstream os;
      os.precision(17);
      os << v;
      text = os.str();
    }
    text = canonical(d, text);
    if (out.empty() || out.back() != text) out.push_back(text);
  }
  return out;
}

std::string ParamSet::describe() const {
  std::ostringstream os;
  for (const auto& d : descs_)
    os << "  " << d.name << " (" << to_string(d.type) << ", " << range_text(d) << ", default " << d.default_value
       << "): " << d.help << "\n";
  return os.str();
}

}  // namespace softgi::render
