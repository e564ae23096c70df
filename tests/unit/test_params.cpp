// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <sstream>

#include "core/context.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/params.h"

using namespace crisp;

static ParamSet makeSet() {
  return ParamSet({{"k", ParamType::Float, -1.0, -4.0, 4.0, nullptr, "threshold weight", "eq. 3.1"},
                   {"n", ParamType::Int, 5, 3, 9, nullptr, "patch size", "alg. 3"},
                   {"on", ParamType::Bool, 1, 0, 1, nullptr, "switch", "-"},
                   {"mask", ParamType::String, 0, 0, 0, "gauss5|box3", "mask kind", "fig. 4.1"}});
}

TEST(Params, DefaultsAndSetters) {
  ParamSet p = makeSet();
  EXPECT_FLOAT_EQ(p.getFloat("k"), -1.0f);
  EXPECT_EQ(p.getInt("n"), 5);
  EXPECT_TRUE(p.getBool("on"));
  EXPECT_EQ(p.getString("mask"), "gauss5");
  p.setFloat("k", 2.5f);
  p.setInt("k", 3);  // an int may set a float
  EXPECT_FLOAT_EQ(p.getFloat("k"), 3.0f);
  p.setFromText("n", "7");
  p.setFromText("on", "false");
  p.setFromText("mask", "box3");
  EXPECT_EQ(p.getInt("n"), 7);
  EXPECT_FALSE(p.getBool("on"));
  EXPECT_EQ(p.getString("mask"), "box3");
}

static std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Exception& e) {
    return e.what();
  }
  return "";
}

TEST(Params, ErrorsNameTheParameter) {
  ParamSet p = makeSet();
  EXPECT_NE(errorOf([&] { p.setFloat("kappa", 1); }).find("unknown parameter 'kappa'"), std::string::npos);
  EXPECT_NE(errorOf([&] { p.setFloat("k", 9); }).find("'k' = 9 is out of range"), std::string::npos);
  EXPECT_NE(errorOf([&] { p.setFloat("k", NAN); }).find("out of range"), std::string::npos);
  EXPECT_NE(errorOf([&] { p.setFloat("n", 4); }).find("'n' is int, not float"), std::string::npos);
  EXPECT_NE(errorOf([&] { p.setFromText("n", "5x"); }).find("expects int"), std::string::npos);
  EXPECT_NE(errorOf([&] { p.setFromText("mask", "gauss7"); }).find("not one of"), std::string::npos);
  EXPECT_NE(errorOf([&] { p.setFromText("on", "maybe"); }).find("expects a bool"), std::string::npos);
  EXPECT_EQ(p.getFloat("k"), -1.0f);  // failed sets leave the value alone
}

// A filter's parameter errors start with the filter's name (the C API's caller
// may hold several), and an int out of range is printed in full.
TEST(Params, FilterErrorsNameTheFilterAndWholeNumbers) {
  Context context;
  std::unique_ptr<Filter> none = createFilter(context, "none");
  EXPECT_EQ(errorOf([&] { none->params().setFloat("bogus", 1); }), "filter 'none': unknown parameter 'bogus' (it has none)");
  std::unique_ptr<Filter> taa = createFilter(context, "taa");
  EXPECT_EQ(errorOf([&] { taa->params().setInt("maxSamples", 2147483647); }),
            "filter 'taa': parameter 'maxSamples' = 2147483647 is out of range [1, 65536]");
  EXPECT_EQ(errorOf([&] { makeSet().setFloat("k", 2.5e9f); }), "parameter 'k' = 2500000000 is out of range [-4, 4]");
  EXPECT_EQ(errorOf([&] { makeSet().setFloat("k", 4.25f); }), "parameter 'k' = 4.25 is out of range [-4, 4]");
  // A value just past a bound prints with the digits that tell it from the bound.
  EXPECT_EQ(errorOf([&] { makeSet().setFloat("k", std::nextafter(4.0f, 5.0f)); }),
            "parameter 'k' = 4.00000048 is out of range [-4, 4]");
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("k", "-4.000004"); }),
            "parameter 'k' = -4.00000381 is out of range [-4, 4]");
  // Text: a number too large to hold is named as typed; blanks on either side are refused alike.
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("n", "99999999999999999999"); }),
            "parameter 'n' = 99999999999999999999 is out of range [3, 9]");
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("k", "1e999"); }), "parameter 'k' = 1e999 is out of range [-4, 4]");
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("n", " 5"); }), "parameter 'n' expects int, got ' 5'");
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("n", "5 "); }), "parameter 'n' expects int, got '5 '");
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("k", "1e-999"); }), "");  // underflows to 0: in range
  EXPECT_EQ(errorOf([&] { makeSet().setFromText("k", "1e39"); }), "parameter 'k' = 1e39 is out of range [-4, 4]");
  ParamSet p = makeSet();  // a bool in any case
  p.setFromText("on", "False");
  EXPECT_FALSE(p.getBool("on"));
  p.setFromText("on", "YES");
  EXPECT_TRUE(p.getBool("on"));
  EXPECT_EQ(errorOf([&] { p.setFromText("on", "Maybe"); }), "parameter 'on' expects a bool (true/false), got 'Maybe'");
}

TEST(Params, TableListsEveryParameter) {
  std::string t = makeSet().table();
  for (const char* n : {"`k`", "`n`", "`on`", "`mask`", "eq. 3.1", "gauss5|box3"}) EXPECT_NE(t.find(n), std::string::npos) << n;
}

// Every filter's float parameters accept their own bounds, as the specs
// (crispGetFilterInfo, the add-on's sliders) give them: set as a float and as
// the text the help table prints. Once, 0.01 read as 0.0099999998f was below
// the double bound 0.01 and refused with "0.01 is out of range [0.01, 4]".
TEST(Params, FloatBoundsAreAccepted) {
  Context context;
  int checked = 0;
  for (const std::string& type : filterTypes()) {
    std::unique_ptr<Filter> f = createFilter(context, type);
    ParamSet& p = f->params();
    for (const ParamSpec& s : p.specs()) {
      if (s.type != ParamType::Float) continue;
      for (double bound : {s.minValue, s.maxValue}) {
        EXPECT_NO_THROW(p.setFloat(s.name, float(bound))) << type << " " << s.name << " = " << bound;
        EXPECT_NO_THROW(p.setFromText(s.name, (std::ostringstream() << bound).str())) << type << " " << s.name << " = " << bound;
        ++checked;
      }
      EXPECT_THROW(p.setFloat(s.name, std::nextafter(float(s.maxValue), INFINITY)), Exception) << type << " " << s.name;
      p.setFloat(s.name, float(s.defaultValue));
    }
  }
  EXPECT_GT(checked, 20);
}
