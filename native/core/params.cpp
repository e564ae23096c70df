// SPDX-License-Identifier: Apache-2.0
#include "core/params.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "core/error.h"

namespace crisp {

const char* paramTypeName(ParamType t) {
  switch (t) {
    case ParamType::Int: return "int";
    case ParamType::Float: return "float";
    case ParamType::Bool: return "bool";
    case ParamType::String: return "string";
  }
  return "?";
}

static std::vector<std::string> splitChoices(const char* choices) {
  std::vector<std::string> out;
  std::string cur;
  for (const char* p = choices ? choices : ""; *p; ++p) {
    if (*p == '|') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += *p;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

// An integer in full (an int parameter's 2147483647, not 2.14748e+09), other
// values as a stream prints them.
static std::string formatNumber(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 1e15) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return buf;
  }
  std::ostringstream s;
  s << v;
  return s.str();
}

// As many digits as it takes to read back as v: a refused float just past 4 is 4.00000048, not "4 is
// out of range [-4, 4]" (params.h).
std::string valueText(double v, bool single) {
  std::string s = formatNumber(v);
  for (int digits : {9, 17}) {
    const double back = std::strtod(s.c_str(), nullptr);
    if (!std::isfinite(v) || (single ? float(back) == float(v) : back == v)) break;
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    s = buf;
  }
  return s;
}

void ParamSet::fail(const std::string& message) const {
  invalidArgument(owner_.empty() ? message : owner_ + ": " + message);
}

ParamSet::ParamSet(std::vector<ParamSpec> specs) : specs_(std::move(specs)) {
  for (const ParamSpec& s : specs_) {
    numbers_.push_back(s.defaultValue);
    auto c = splitChoices(s.choices);
    strings_.push_back(c.empty() ? std::string() : c.front());
  }
}

std::size_t ParamSet::indexOf(const std::string& name) const {
  for (std::size_t i = 0; i < specs_.size(); ++i)
    if (name == specs_[i].name) return i;
  std::string known;
  for (const ParamSpec& s : specs_) known += std::string(known.empty() ? "" : ", ") + s.name;
  fail("unknown parameter '" + name + "'" + (known.empty() ? std::string(" (it has none)") : " (known: " + known + ")"));
}

const ParamSpec& ParamSet::spec(const std::string& name) const { return specs_[indexOf(name)]; }

void ParamSet::checkType(const ParamSpec& s, ParamType want) const {
  if (s.type != want)
    fail(std::string("parameter '") + s.name + "' is " + paramTypeName(s.type) + ", not " +
                    paramTypeName(want));
}

void ParamSet::checkRange(const ParamSpec& s, double v) const {
  // A float parameter holds a float: its bounds as floats too, so the value
  // a caller reads from the specs (0.01 becomes 0.0099999998f) is accepted.
  const bool single = s.type == ParamType::Float;
  const double lo = single ? double(float(s.minValue)) : s.minValue;
  const double hi = single ? double(float(s.maxValue)) : s.maxValue;
  if (!std::isfinite(v) || v < lo || v > hi)
    fail(std::string("parameter '") + s.name + "' = " + valueText(v, single) + " is out of range [" +
                    formatNumber(s.minValue) + ", " + formatNumber(s.maxValue) + "]");
}

void ParamSet::setInt(const std::string& name, int value) {
  std::size_t i = indexOf(name);
  // An int may set a float parameter (as OIDN does); the reverse is an error.
  if (specs_[i].type != ParamType::Float) checkType(specs_[i], ParamType::Int);
  checkRange(specs_[i], value);
  numbers_[i] = value;
}

void ParamSet::setFloat(const std::string& name, float value) {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::Float);
  checkRange(specs_[i], value);
  numbers_[i] = value;
}

void ParamSet::setBool(const std::string& name, bool value) {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::Bool);
  numbers_[i] = value ? 1.0 : 0.0;
}

void ParamSet::setString(const std::string& name, const std::string& value) {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::String);
  auto choices = splitChoices(specs_[i].choices);
  for (const auto& c : choices)
    if (c == value) {
      strings_[i] = value;
      return;
    }
  fail("parameter '" + name + "' = '" + value + "' is not one of: " + specs_[i].choices);
}

void ParamSet::setFromText(const std::string& name, const std::string& text) {
  const ParamSpec& s = spec(name);
  auto parseNumber = [&](bool integer) {
    const char* b = text.c_str();
    char* e = nullptr;
    errno = 0;
    double v = integer ? double(std::strtol(b, &e, 10)) : std::strtod(b, &e);
    // strtol / strtod skip leading blanks; a trailing one is refused, so a leading one is too.
    if (text.empty() || std::isspace((unsigned char)text[0]) || *e != '\0')
      fail("parameter '" + name + "' expects " + paramTypeName(s.type) + ", got '" + text + "'");
    // Too large to hold (for a float parameter: as a float): say what was typed.
    if ((errno == ERANGE && (integer || std::fabs(v) > 1.0)) ||
        (!integer && std::isfinite(v) && std::fabs(v) > double(std::numeric_limits<float>::max())))
      fail("parameter '" + name + "' = " + text + " is out of range [" + formatNumber(s.minValue) + ", " +
           formatNumber(s.maxValue) + "]");
    return v;
  };
  switch (s.type) {
    case ParamType::Int: {
      double v = parseNumber(true);
      checkRange(s, v);
      setInt(name, int(v));
      break;
    }
    case ParamType::Float: setFloat(name, float(parseNumber(false))); break;
    case ParamType::Bool: {
      std::string word = text;  // any case, as the add-on reads a bool
      for (char& c : word) c = char(std::tolower((unsigned char)c));
      if (word == "1" || word == "true" || word == "on" || word == "yes") setBool(name, true);
      else if (word == "0" || word == "false" || word == "off" || word == "no") setBool(name, false);
      else fail("parameter '" + name + "' expects a bool (true/false), got '" + text + "'");
      break;
    }
    case ParamType::String: setString(name, text); break;
  }
}

int ParamSet::getInt(const std::string& name) const {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::Int);
  return int(numbers_[i]);
}
float ParamSet::getFloat(const std::string& name) const {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::Float);
  return float(numbers_[i]);
}
bool ParamSet::getBool(const std::string& name) const {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::Bool);
  return numbers_[i] != 0.0;
}
const std::string& ParamSet::getString(const std::string& name) const {
  std::size_t i = indexOf(name);
  checkType(specs_[i], ParamType::String);
  return strings_[i];
}

std::string jsonQuote(const std::string& s) {
  std::string o = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += char(c);
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      o += buf;
    } else {
      o += char(c);
    }
  }
  return o + "\"";
}

std::string ParamSet::json() const {
  std::ostringstream o;
  o << "[";
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    const ParamSpec& s = specs_[i];
    o << (i ? ", " : "") << "{\"name\": " << jsonQuote(s.name) << ", \"type\": " << jsonQuote(paramTypeName(s.type));
    switch (s.type) {
      case ParamType::Bool: o << ", \"default\": " << (s.defaultValue != 0 ? "true" : "false"); break;
      case ParamType::String: {
        auto c = splitChoices(s.choices);
        o << ", \"default\": " << jsonQuote(c.empty() ? "" : c.front()) << ", \"choices\": [";
        for (std::size_t k = 0; k < c.size(); ++k) o << (k ? ", " : "") << jsonQuote(c[k]);
        o << "]";
        break;
      }
      default:
        o << ", \"default\": " << formatNumber(s.defaultValue) << ", \"min\": " << formatNumber(s.minValue)
          << ", \"max\": " << formatNumber(s.maxValue);
    }
    o << ", \"meaning\": " << jsonQuote(s.meaning ? s.meaning : "") << ", \"source\": " << jsonQuote(s.source ? s.source : "")
      << "}";
  }
  o << "]";
  return o.str();
}

std::string ParamSet::table() const {
  std::ostringstream o;
  o << "| name | type | default | range | meaning | source |\n|---|---|---|---|---|---|\n";
  for (const ParamSpec& s : specs_) {
    o << "| `" << s.name << "` | " << paramTypeName(s.type) << " | ";
    switch (s.type) {
      case ParamType::Bool: o << (s.defaultValue != 0 ? "true" : "false") << " | true, false"; break;
      case ParamType::String: {
        auto c = splitChoices(s.choices);
        o << (c.empty() ? "" : c.front()) << " | " << s.choices;
        break;
      }
      default: o << formatNumber(s.defaultValue) << " | " << formatNumber(s.minValue) << " .. " << formatNumber(s.maxValue);
    }
    o << " | " << s.meaning << " | " << s.source << " |\n";
  }
  return o.str();
}

}  // namespace crisp
