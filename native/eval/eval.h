// SPDX-License-Identifier: Apache-2.0
// `crisp eval`, after Blender has rendered OUTDIR/renders (addon/crisp/batch_eval.py):
// runs every method through the library, measures everything against the
// reference, and writes OUTDIR/results.json, results.csv, images/ and report.html.
#pragma once

#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace crisp::eval {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Options {
  std::string outDir;                // OUTDIR
  std::string renderDir;             // OUTDIR/renders, Blender's output (scene.json inside)
  std::vector<std::string> methods;  // method specs (parseMethodSpec), in the order given
  int threads = 0;
  bool quiet = false;
  std::string command;               // the exact command line, for the page
  double blenderSeconds = 0;         // wall time of the Blender stage in this run
  int warmup = 0;                    // the first frames: measured and listed, left out of the error means
  nlohmann::json panel;              // what came from the .blend's Crisp panel (batch_eval.py --read-panel's
                                     // record; "row": the method spec measuring its setting), null: nothing
};

struct FrameFigures {
  int frame = 0;
  double psnr = kNaN, ssim = kNaN, flip = kNaN, rmse = kNaN;
  double temporalError = kNaN;  // none for the first frame
  double renderS = kNaN, filterS = kNaN;
  std::string file;  // the image measured, relative to OUTDIR
};

// A method as `crisp eval --methods` names it: a library method, optionally with parameters,
// "taa:feedbackMin=0.7:sharpen=0.2", so that settings can be compared side by side in one report.
struct MethodSpec {
  std::string method;                                       // library filter type ("taa")
  std::vector<std::pair<std::string, std::string>> params;  // in the order given
  bool gives(const std::string& key) const {
    for (const auto& kv : params)
      if (kv.first == key) return true;
    return false;
  }
};
// Splits a spec at ':' into the method and KEY=VALUE pairs; throws std::invalid_argument naming
// the malformed part. Does not check the method or the keys (the library does, when they are set).
MethodSpec parseMethodSpec(const std::string& spec);

// One line of the results: a library method, Blender's SMAA, or a point of EEVEE's curve.
struct Entry {
  std::string name;      // as given: the spec of a method ("taa:feedbackMin=0.7")
  std::string method;    // the library method (kind "method"), else the name
  std::string kind;      // "method" | "blender" | "eevee"
  int samples = 1;       // EEVEE samples of its input
  std::string inputSet;  // renders/<set> its input came from
  bool temporal = false;
  bool subsamplesRendered = true;  // false: its plan renders no geometric sub-samples (rsaa, nothing visible)
  bool panel = false;    // the setting of the scene's Crisp panel (Options::panel "row")
  // What the scene's plan sets (scene.json "plans" "params") where the spec does not, as text.
  std::vector<std::pair<std::string, std::string>> planParams;
  std::string error;     // not empty: the method failed, this says why
  std::vector<FrameFigures> frames;
  double psnr = kNaN, ssim = kNaN, flip = kNaN, temporalError = kNaN;
  double renderS = kNaN, filterS = kNaN, timeS = kNaN;  // means per frame; timeS = render + filter
  double equivalentSamples = kNaN;
  std::string equivalentNote;  // "< 1", "> 16" when outside the curve
  bool pareto = false;
};

struct Crop {
  int x = 0, y = 0, size = 0;
  double score = 0;  // mean squared error of the 1-sample frames there, per pixel and frame
};

// Runs, measures and writes everything; returns the process exit code (0 even
// when a method failed: the failure is in the results and the page).
int run(const Options& options);

// Equivalent EEVEE samples of `psnr` on the curve (samples ascending, PSNR per
// count): linear interpolation of log2(samples) against PSNR on the first
// segment that brackets it. NaN with note "< S0" / "> Sn" outside the curve.
double equivalentSamples(const std::vector<int>& samples, const std::vector<double>& psnr, double value,
                         std::string* note);

// Writes OUTDIR/report.html from the results JSON (results.json's content).
void writeReport(const std::string& outDir, const nlohmann::json& results);

}  // namespace crisp::eval
