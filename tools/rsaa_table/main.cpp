// SPDX-License-Identifier: Apache-2.0
// crisp_rsaa_table: generates RSAA's resampling-offset table (seed 003,
// section 2.3.2) for a sub-sample pattern and writes it as the C++ source
// the library ships (native/rsaa/offset_table.cpp). The model and the
// fitting are in native/rsaa/table_generator.h.
//
//   crisp_rsaa_table [--output FILE] [--seed N] [--configurations N]
//                    [--pattern "x0,y0;x1,y1;...;x7,y7"] [--check FILE]
//
// The pattern is in pixels, x right, y DOWN (the add-on's RSAA_PATTERN with
// y negated); the default is rsaa::kDefaultPattern. --check compares the
// generated text with FILE and exits 1 if they differ.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "core/error.h"
#include "rsaa/table_generator.h"

namespace {

[[noreturn]] void usage(const std::string& why) {
  std::cerr << "crisp_rsaa_table: " << why
            << "\nusage: crisp_rsaa_table [--output FILE] [--seed N] [--configurations N] "
               "[--pattern \"x0,y0;...;x7,y7\"] [--check FILE]\n";
  std::exit(2);
}

crisp::rsaa::Pattern parsePattern(const std::string& text) {
  crisp::rsaa::Pattern p{};
  std::istringstream in(text);
  std::string item;
  int k = 0;
  while (std::getline(in, item, ';')) {
    if (k >= crisp::rsaa::kSamples) usage("--pattern has more than 8 points");
    float x, y;
    char comma;
    std::istringstream pt(item);
    if (!(pt >> x >> comma >> y) || comma != ',') usage("--pattern point '" + item + "' is not 'x,y'");
    p.x[k] = x;
    p.y[k] = y;
    ++k;
  }
  if (k != crisp::rsaa::kSamples) usage("--pattern needs exactly 8 points, got " + std::to_string(k));
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  crisp::rsaa::GeneratorOptions options;
  std::string output, check;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    try {
      if (a == "--output") output = value();
      else if (a == "--check") check = value();
      else if (a == "--seed") options.seed = std::uint32_t(std::stoul(value()));
      else if (a == "--configurations") options.configurations = std::stol(value());
      else if (a == "--pattern") options.pattern = parsePattern(value());
      else if (a == "--help" || a == "-h") usage("help");
      else usage("unknown argument '" + a + "'");
    } catch (const std::logic_error&) {
      usage("bad number for " + a);
    }
  }
  try {
    const std::string text = crisp::rsaa::offsetTableSource(crisp::rsaa::generateOffsetTable(options));
    if (!check.empty()) {
      std::ifstream in(check, std::ios::binary);
      if (!in) {
        std::cerr << "crisp_rsaa_table: cannot read '" << check << "'\n";
        return 2;
      }
      std::ostringstream shipped;
      shipped << in.rdbuf();
      if (shipped.str() != text) {
        std::cerr << "crisp_rsaa_table: '" << check << "' differs from a fresh run\n";
        return 1;
      }
      std::cout << "crisp_rsaa_table: '" << check << "' equals a fresh run\n";
    }
    if (!output.empty()) {
      std::ofstream out(output, std::ios::binary);
      out << text;
      if (!out) {
        std::cerr << "crisp_rsaa_table: cannot write '" << output << "'\n";
        return 2;
      }
    } else if (check.empty()) {
      std::cout << text;
    }
  } catch (const crisp::Exception& e) {
    std::cerr << "crisp_rsaa_table: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
