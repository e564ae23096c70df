// SPDX-License-Identifier: Apache-2.0
// Typed, named filter parameters. Each filter declares a table of ParamSpec
// beside its code; that table is the parameter documentation (printed by
// `crisp help METHOD` and crispGetFilterDoc) and the validator.
#pragma once

#include <string>
#include <vector>

namespace crisp {

enum class ParamType { Int, Float, Bool, String };
const char* paramTypeName(ParamType t);
// JSON string literal (quotes and escapes included).
std::string jsonQuote(const std::string& s);
// v in the fewest digits that read back as it (0.001, 4.00000048, 2147483647); `single`: v is a float's
// value, which nine digits give back.
std::string valueText(double v, bool single);

struct ParamSpec {
  const char* name;
  ParamType type;
  double defaultValue;       // Int/Float/Bool
  double minValue;           // inclusive range for Int/Float
  double maxValue;
  const char* choices;       // String: '|'-separated allowed values; first is default
  const char* meaning;
  const char* source;        // equation / section of the source document
};

// Current values of one filter's parameters, validated against its specs.
class ParamSet {
 public:
  explicit ParamSet(std::vector<ParamSpec> specs);

  const std::vector<ParamSpec>& specs() const { return specs_; }
  // Whose parameters these are ("filter 'taa'"): the start of every error message.
  void setOwner(std::string owner) { owner_ = std::move(owner); }
  const ParamSpec& spec(const std::string& name) const;  // throws naming the unknown parameter

  void setInt(const std::string& name, int value);
  void setFloat(const std::string& name, float value);
  void setBool(const std::string& name, bool value);
  void setString(const std::string& name, const std::string& value);
  // Parses "value" according to the parameter's type (CLI --set KEY=VALUE).
  void setFromText(const std::string& name, const std::string& text);

  int getInt(const std::string& name) const;
  float getFloat(const std::string& name) const;
  bool getBool(const std::string& name) const;
  const std::string& getString(const std::string& name) const;

  // Markdown table: name | type | default | range | meaning | source.
  std::string table() const;
  // JSON array: [{"name", "type", "default", "min", "max", "choices", "meaning", "source"}, ...]
  std::string json() const;

 private:
  std::size_t indexOf(const std::string& name) const;
  void checkType(const ParamSpec& s, ParamType want) const;
  void checkRange(const ParamSpec& s, double v) const;
  [[noreturn]] void fail(const std::string& message) const;
  std::string owner_;
  std::vector<ParamSpec> specs_;
  std::vector<double> numbers_;
  std::vector<std::string> strings_;
};

}  // namespace crisp
