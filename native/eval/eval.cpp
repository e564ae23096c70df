// SPDX-License-Identifier: Apache-2.0
// `crisp eval` after the renders: methods, measurements, results files (eval.h).
#include "eval/eval.h"

#include <sys/prctl.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <unistd.h>

#include <OpenImageIO/oiioversion.h>

#include <algorithm>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstring>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <thread>
#include <vector>

#include "cli/commands.h"
#include "cli/progress.h"
#include "cli/stop_notice.h"
#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "crisp/crisp.h"
#include "io/frame.h"
#include "io/subsamples.h"
#include "metrics/metrics.h"
#include "metrics/temporal_error.h"
#include "motion/reconstruct.h"

namespace crisp::eval {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

MethodSpec parseMethodSpec(const std::string& spec) {
  MethodSpec out;
  size_t start = 0, colon = spec.find(':');
  out.method = spec.substr(0, colon);
  if (out.method.empty()) throw std::invalid_argument("method '" + spec + "' has no name before ':'");
  while (colon != std::string::npos) {
    start = colon + 1;
    colon = spec.find(':', start);
    const std::string kv = spec.substr(start, colon == std::string::npos ? std::string::npos : colon - start);
    const size_t eq = kv.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == kv.size())
      throw std::invalid_argument("method '" + spec + "': expected KEY=VALUE after ':', got '" + kv + "'");
    out.params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
  }
  return out;
}

namespace {

std::string frameName(int f, const char* ext = ".exr") {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%04d%s", f, ext);
  return buf;
}

std::string frameKey(int f) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04d", f);
  return buf;
}

json readJson(const fs::path& path, bool required) {
  std::ifstream in(path);
  if (!in) {
    if (required) ioError("cannot read '" + path.string() + "'");
    return json::object();
  }
  try {
    return json::parse(in);
  } catch (const std::exception& e) {
    if (required) invalidData("'" + path.string() + "' is not valid JSON: " + e.what());
    return json::object();
  }
}

void writeJson(const fs::path& path, const json& j) { cli::writeTextFile(path.string(), j.dump(1) + "\n"); }

double mean(const std::vector<double>& v) {
  double s = 0;
  int n = 0;
  for (double x : v)
    if (std::isfinite(x)) s += x, ++n;
  return n ? s / n : kNaN;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Per-frame render seconds of one render set (renders/<set>/times.json).
std::map<int, double> renderTimes(const fs::path& dir) {
  std::map<int, double> t;
  json j = readJson(dir / "times.json", false);
  for (auto it = j.begin(); it != j.end(); ++it) t[std::stoi(it.key())] = it.value().get<double>();
  return t;
}

// What a render set's frames cost Blender: (samples, sorted passes) for a curve set eevee_N (colour
// alone) and the 1-sample input sets scene.json lists; another set (the reference) has no key.
std::optional<std::pair<int, std::vector<std::string>>> renderWork(const json& scene, const std::string& set) {
  if (set.rfind("eevee_", 0) == 0) return std::make_pair(std::stoi(set.substr(6)), std::vector<std::string>{"color"});
  const json sets = scene.value("sets", json::object());
  if (!sets.contains(set) || !sets[set].contains("passes")) return std::nullopt;
  auto passes = sets[set]["passes"].get<std::vector<std::string>>();
  std::sort(passes.begin(), passes.end());
  return std::make_pair(1, passes);
}

// Per-frame render seconds of `set`, each the mean over the sets that do the same work (renderWork):
// a colour-only jittered set and eevee_1 differ only by the camera's sub-pixel shift, and both are
// timed alike (render.py _render_to), so the gap between their medians is the machine's noise; taken
// apart it once ranked taa (the jittered set) faster than the plain 1-sample render.
std::map<int, double> sameWorkRenderTimes(const fs::path& renders, const json& scene, const std::string& set) {
  const auto work = renderWork(scene, set);
  if (!work) return renderTimes(renders / set);
  std::vector<std::string> names;
  const json sets = scene.value("sets", json::object());  // kept: items() of a temporary would dangle
  for (const auto& [name, unused] : sets.items()) names.push_back(name);
  for (int s : scene.value("curve", std::vector<int>{})) names.push_back("eevee_" + std::to_string(s));
  std::map<int, std::pair<double, int>> sums;
  for (const std::string& name : names) {
    if (renderWork(scene, name) != work) continue;
    for (const auto& [frame, seconds] : renderTimes(renders / name)) {
      sums[frame].first += seconds;
      ++sums[frame].second;
    }
  }
  std::map<int, double> times;
  for (const auto& [frame, sum] : sums) times[frame] = sum.first / sum.second;
  return times;
}

// ---- the methods ---------------------------------------------------------------------------------


// Motion for the frames of a render set that has depth (a jittered set, renders/warp) of a
// scene where something moves: the renderer's pass, else reconstructed from
// depth and the sidecars. A still scene gets none, as its pass plan says, so
// the temporal filters take their static path.
void addMotion(Frame& frame, const fs::path& inputDir, int f, int firstFrame, bool sceneMoves, int threads) {
  if (!sceneMoves || frame.has("motion") || f == firstFrame || !frame.has("depth")) return;
  fs::path prev = inputDir / frameName(f - 1, ".json");
  if (fs::exists(prev)) reconstructFrameMotion(frame, prev.string(), "", threads);
}

// The temporal error's warp W and disocclusion test (METHODS.md "Metrics") describe the pixel
// centres of the images compared (the outputs and the reference): they come from renders/warp, the
// unjittered 1-sample frames with depth, motion and IDs (plan.py TEMPORAL_ERROR). A jittered frame's
// motion, depth and IDs describe the point at p + jitter (up to 1.5 px away), another surface along
// every edge that moves against what lies behind it; they serve only when renders/warp cannot.
struct WarpGeometry {
  std::map<int, Image> motions, masks;  // by frame (from the second frame on)
  std::string description;              // for the report; empty: none found (W = identity)
  std::string idsUnusable;              // why the mask goes without IDs the frames hold (Frame::unusable)
};

// Motion (the renderer's, else reconstructed from depth and the sidecars) and the disocclusion mask
// of each frame after the first, from the frames in dir. first: that folder's first frame when the
// caller has read it already. Throws on unreadable frames or motion that cannot be reconstructed.
void loadWarpGeometry(const fs::path& dir, const std::vector<int>& frames, int threads, WarpGeometry& g,
                      std::unique_ptr<Frame> first) {
  std::unique_ptr<Frame> prev;
  for (int f : frames) {
    auto fr = f == frames.front() && first ? std::move(first)
                                           : std::make_unique<Frame>(readFrame((dir / frameName(f)).string()));
    addMotion(*fr, dir, f, frames.front(), true, threads);
    if (prev && fr->has("motion")) {
      g.motions[f] = fr->pass("motion");
      const Image* ids = fr->has("id") ? &fr->pass("id") : nullptr;
      const Image* idsPrev = prev->has("id") ? &prev->pass("id") : nullptr;
      const Image* depth = fr->has("depth") ? &fr->pass("depth") : nullptr;
      const Image* depthPrev = prev->has("depth") ? &prev->pass("depth") : nullptr;
      for (const Frame* held : {fr.get(), prev.get()})
        if (!(ids && idsPrev) && held->unusable.count("id") && g.idsUnusable.empty())
          g.idsUnusable = held->unusable.at("id");
      if ((ids && idsPrev) || (depth && depthPrev))
        g.masks[f] = disocclusionMask(&g.motions[f], ids, idsPrev, depth, depthPrev, 0.1f, threads);
    }
    prev = std::move(fr);
  }
}

// renders/warp when its frames carry the passes its plan (scene.json "sets") lists, else a jittered
// set with depth (the one with most passes first); the first that loads. Each one passed over is said
// on stderr (unless quiet).
WarpGeometry warpGeometry(const fs::path& renders, const json& scene, const std::vector<int>& frames,
                          const Options& o) {
  const fs::path warp = renders / "warp";
  std::vector<std::pair<std::size_t, std::string>> jitteredSets;  // (pass count, name) with depth
  const json sets = scene.value("sets", json::object());
  for (const auto& [name, set] : sets.items()) {
    const json passes = set.value("passes", json::array());
    if (set.value("jitter", false) && std::find(passes.begin(), passes.end(), "depth") != passes.end())
      jitteredSets.push_back({passes.size(), name});
  }
  std::sort(jitteredSets.begin(), jitteredSets.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  auto note = [&](const std::string& text) {
    if (!o.quiet) std::fprintf(stderr, "crisp eval: the temporal error's warp: %s\n", text.c_str());
  };
  struct Candidate {
    fs::path dir;
    const char* description;
    std::unique_ptr<Frame> first;  // read already (the probe of renders/warp)
  };
  std::vector<Candidate> candidates;
  if (!fs::exists(warp / frameName(frames.front()))) {
    note("no unjittered geometry in " + warp.string() + "; using the jittered frames' motion");
  } else {
    std::string missing;
    auto probe = std::make_unique<Frame>(readFrame((warp / frameName(frames.front())).string()));
    const json passes = scene.value("sets", json::object()).value("warp", json::object()).value("passes", json::array());
    for (const std::string pass : {"depth", "motion", "id"})
      if (std::find(passes.begin(), passes.end(), pass) != passes.end() && !probe->has(pass) &&
          !(pass == "motion" && probe->has("depth")))  // motion is reconstructed from depth
        missing += (missing.empty() ? "" : ", ") + pass +
                   (probe->unusable.count(pass) ? " (held unusable: " + probe->unusable.at(pass) + ")" : "");
    if (missing.empty())
      candidates.push_back({warp, "motion vectors at the pixel centres (unjittered 1-sample frames)", std::move(probe)});
    else
      note(warp.string() + " lacks " + missing + " (delete it and run eval again to render it); using the "
           "jittered frames' motion");
  }
  for (const auto& [count, name] : jitteredSets)
    candidates.push_back({renders / name, "motion vectors of the jittered 1-sample frames (they describe the point at "
                                          "p + jitter: approximate along moving edges)",
                          nullptr});
  for (Candidate& c : candidates) {
    if (!fs::exists(c.dir / frameName(frames.front()))) continue;
    WarpGeometry g;
    try {
      loadWarpGeometry(c.dir, frames, o.threads, g, std::move(c.first));
    } catch (const Exception& ex) {
      note(c.dir.string() + ": " + ex.what() + (&c != &candidates.back() ? "; trying the next source" : ""));
      continue;
    }
    if (g.motions.empty()) continue;
    g.description = c.description;
    if (!g.idsUnusable.empty() && !g.masks.empty())  // said, not silent: the mask then tests depth alone
      note("the disocclusion test goes without object IDs: " + g.idsUnusable);
    return g;
  }
  return {};
}

// What identifies an input frame a method read: its render set, size and modification time. A
// render set's frame rendered again (other passes or settings, render.reusable_input) is a new file
// with a new time, and a method's frame made from the old one is then stale. (A copy of an eval
// folder must keep modification times, as cp -a does, or every method is computed again.)
std::string inputStamp(const fs::path& file) {
  const std::string stamp = cli::sizeAndTime(file.string());
  return stamp.empty() ? "" : (file.parent_path().filename() / file.filename()).string() + " " + stamp;
}

void runMethod(Entry& e, const Options& o, const std::vector<int>& frames, const fs::path& inputDir, bool sceneMoves,
               cli::Progress& progress) {
  const fs::path dir = fs::path(o.outDir) / "methods" / e.name;
  cli::makeDirectories(dir.string());
  json times = readJson(dir / "times.json", false);
  // inputs.json: the stamp (inputStamp) of the input each frame was made from.
  json inputs = readJson(dir / "inputs.json", false);
  if (!times.is_object()) times = json::object();  // valid JSON of another shape: nothing recorded
  if (!inputs.is_object()) inputs = json::object();
  const fs::path stampFile = dir / "build.txt";
  std::string stamp;
  if (std::ifstream in(stampFile); in) std::getline(in, stamp);
  if (stamp != cli::buildStamp()) {
    // Frames of another build (or of a folder from before the stamp): none counts as done. The
    // emptied times go first, so an interrupted run never pairs old frames with the new stamp.
    if (!times.empty() && !o.quiet)
      std::fprintf(stderr, "crisp eval: methods/%s was made by another crisp build; computing it again\n",
                   e.name.c_str());
    times = json::object();
    writeJson(dir / "times.json", times);
    cli::writeTextFile(stampFile.string(), cli::buildStamp() + "\n");
  }
  std::map<int, std::string> inputNow;
  for (int f : frames) inputNow[f] = inputStamp(inputDir / frameName(f));
  auto made = [&](int f) { return times.contains(frameKey(f)) && fs::exists(dir / frameName(f)); };
  auto done = [&](int f) {
    return made(f) && inputs.contains(frameKey(f)) && inputs[frameKey(f)] == inputNow[f];
  };
  if (!o.quiet && std::any_of(frames.begin(), frames.end(), [&](int f) { return made(f) && !done(f); }))
    std::fprintf(stderr, "crisp eval: methods/%s: frames whose input frame changed (or was not recorded); computing "
                 "them again\n", e.name.c_str());
  bool allDone = std::all_of(frames.begin(), frames.end(), done);
  // A temporal method's frame depends on the history of all earlier ones: a partial run starts over,
  // and so does a run whose history started at another frame (inputs.json "history_from"; frames 3-4
  // of a run over 1-4 are not those of a run over 3-4).
  if (e.temporal && inputs.value("history_from", json()) != json(frames.front())) {
    if (allDone && !o.quiet)
      std::fprintf(stderr, "crisp eval: methods/%s: its history started at another frame; computing it again\n",
                   e.name.c_str());
    allDone = false;
  }
  if (!allDone && e.temporal) {
    times = json::object();
    inputs["history_from"] = frames.front();
  }
  Context context;
  context.setInt("numThreads", o.threads);
  std::unique_ptr<Filter> filter = createFilter(context, e.method);
  const MethodSpec spec = parseMethodSpec(e.name);
  for (const auto& [key, value] : spec.params) filter->params().setFromText(key, value);
  // What the scene's plan asks of the filter (a still-pixel average switched off where the image changes
  // with nothing moving), as the add-on runs it: only keys the row's settings do not give (run()).
  for (const auto& [key, value] : e.planParams) filter->params().setFromText(key, value);
  // rsaa on a plan that rendered no geometry (no visible object, so no geometric edge) keeps every
  // colour, as the add-on filters it (native.FrameFilter): 'none'; setting its parameters above checked them.
  if (readsSubsamples(*filter) && !e.subsamplesRendered) filter = createFilter(context, "none");
  Image output;
  cli::ShotPosition shot;
  const bool needsMotion = cli::readsMotion(*filter);
  // The renders' Film > Filter Size (their sidecars; CRISP_EVAL_FILTER_SIZE sets it) unless the method's settings give one.
  shot.filterSizeGiven = spec.gives("filterSize");
  for (int f : frames) {
    if (!e.temporal ? done(f) : allDone) {
      progress.step(e.name + " frame " + std::to_string(f) + " (done before)");
      continue;
    }
    const fs::path in = inputDir / frameName(f);
    Frame frame = readFrame(in.string());
    // A cut to another camera (or a gap in the frame numbers): the history starts over (cli/files.cpp).
    // Said also under --quiet, as crisp filter says it: quiet hides progress, not this.
    const std::string cut = cli::historyBreak(*filter, in.string(), shot);
    if (!cut.empty()) {
      filter->reset();
      std::fprintf(stderr, "crisp eval: %s frame %d: history starts over (%s)\n", e.name.c_str(), f, cut.c_str());
    }
    // The motion a temporal method reads is rebuilt from depth and the sidecars (EEVEE 3.4 writes no
    // Vector pass): work the method costs every frame, timed with its filter.
    const auto motionStart = Clock::now();
    if (needsMotion) addMotion(frame, inputDir, f, cut.empty() ? frames.front() : f, sceneMoves, o.threads);
    const double motionSeconds = std::chrono::duration<double>(Clock::now() - motionStart).count();
    cli::bindFrame(*filter, frame, shot);
    if (output.width != frame.width || output.height != frame.height) output = Image(frame.width, frame.height, 4);
    filter->setImage("output", output.view());
    auto t0 = Clock::now();
    try {
      if (!filter->committed()) filter->commit();
      filter->execute();
    } catch (const Exception& ex) {
      throw Exception(ex.code(), "'" + in.string() + "': " + ex.what());
    }
    double seconds = std::chrono::duration<double>(Clock::now() - t0).count() + motionSeconds;
    writeImage((dir / frameName(f)).string(), output);
    writeImage((dir / frameName(f, ".png")).string(), output);
    times[frameKey(f)] = seconds;
    writeJson(dir / "times.json", times);
    inputs[frameKey(f)] = inputNow[f];  // after times: an interruption between them only recomputes
    writeJson(dir / "inputs.json", inputs);
    progress.step(e.name + " frame " + std::to_string(f));
  }
}

// ---- RSAA: geometric-edge pixels and the extra geometry renders (issue 5) -------------------------

// Thresholds of "another surface" between two geometric samples of one pixel.
constexpr float kEdgeDepthJump = 0.05f;   // relative planar depth difference
constexpr float kEdgeCreaseCos = 0.9397f; // cos(20 deg): normals further apart are a crease

// Geometric-edge pixels of a frame (1 = edge) from the geometry of rsaa's input set: the pixel-centre
// depth and normal and the 8 geometric sub-samples, i.e. 9 points inside the pixel's square. A pixel
// is an edge pixel when some sub-sample lies on another surface than the centre: background against
// geometry, a planar depth differing by more than 5 %, or normals more than 20 degrees apart. This
// is the geometry at 9x the 1-sample density, independent of RSAA's own SADP test and threshold.
Image geometricEdgeMask(const Frame& frame) {
  const Image& depth = frame.pass("depth");
  const Image& normal = frame.pass("normal");
  Image mask(frame.width, frame.height, 1);
  for (int y = 0; y < frame.height; ++y)
    for (int x = 0; x < frame.width; ++x) {
      const float d = depth.at(x, y)[0];
      const float* n = normal.at(x, y);
      bool edge = false;
      for (int k = 0; k < 8 && !edge; ++k) {
        const float* s = frame.pass(subsamplePass(k)).at(x, y);
        const bool bg = isBackgroundDepth(d), sbg = isBackgroundDepth(s[3]);
        if (bg || sbg) {
          edge = bg != sbg;
          continue;
        }
        const float dot = n[0] * s[0] + n[1] * s[1] + n[2] * s[2];
        edge = std::fabs(s[3] - d) > kEdgeDepthJump * std::fmin(d, s[3]) || !(dot >= kEdgeCreaseCos);
      }
      mask.at(x, y)[0] = edge ? 1.0f : 0.0f;
    }
  return mask;
}

// Seconds Blender spent on a frame's 8 geometry renders (the sidecar's subsamples[].render_s).
double geometryRenderSeconds(const fs::path& exr) {
  fs::path side = exr;
  side.replace_extension(".json");
  double total = 0;
  for (const SubsampleEntry& s : readSubsampleList(side.string())) total += s.renderSeconds;
  return total;
}

// Per-entry figures beyond FrameFigures: PSNR over the geometric-edge pixels and, for rsaa, the
// geometry render seconds (frame -> value).
struct EdgeFigures {
  std::map<int, double> edgePsnr, geometryS;
};

// ---- measuring -----------------------------------------------------------------------------------

Image crop(const Image& img, const Crop& c) {
  Image out(c.size, c.size, img.channels);
  for (int y = 0; y < c.size; ++y)
    std::copy(img.at(c.x, c.y + y), img.at(c.x, c.y + y) + std::size_t(c.size) * std::size_t(img.channels), out.at(0, y));
  return out;
}

// A sequential colour map (dark blue -> red -> yellow -> white) for the error maps, returned as
// LINEAR values so that writeImage's sRGB encoding puts the intended colour in the PNG.
void heat(float t, float* rgb) {
  t = std::fmin(std::fmax(t, 0.0f), 1.0f);
  static const float stops[5][3] = {{0.02f, 0.02f, 0.1f}, {0.3f, 0.05f, 0.5f}, {0.85f, 0.2f, 0.2f},
                                    {1.0f, 0.75f, 0.1f}, {1.0f, 1.0f, 0.9f}};
  float s = t * 4.0f;
  int i = std::min(int(s), 3);
  float u = s - float(i);
  for (int c = 0; c < 3; ++c) rgb[c] = srgbDecode(stops[i][c] * (1 - u) + stops[i + 1][c] * u);
}

void writeMap(const fs::path& path, const Image& map, float (*scale)(float)) {
  Image out(map.width, map.height, 3);
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) heat(scale(map.at(x, y)[0]), out.at(x, y));
  writeImage(path.string(), out);
}

// Squared error -> absolute error over a 0.25 full scale (sRGB units).
float errorScale(float sq) { return std::sqrt(std::fmax(sq, 0.0f)) / 0.25f; }
float ssimScale(float s) { return 1.0f - s; }
float flipScale(float v) { return v; }
// Mean per-pixel temporal error over a 0.05 full scale (sRGB units).
float temporalScale(float v) { return v / 0.05f; }

// The most aliased places: windows with the largest 1-sample error (errorMean: per pixel, the mean over
// frames of the squared error), greedily, not overlapping.
std::vector<Crop> chooseCrops(const Image& errorMean, int count) {
  const int w = errorMean.width, h = errorMean.height;
  const int size = std::max(8, std::min({64, (std::min(w, h) + 4) / 5, std::min(w, h)}));
  std::vector<double> integral(std::size_t(w + 1) * std::size_t(h + 1), 0.0);
  auto I = [&](int x, int y) -> double& { return integral[std::size_t(y) * std::size_t(w + 1) + std::size_t(x)]; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) I(x + 1, y + 1) = errorMean.at(x, y)[0] + I(x, y + 1) + I(x + 1, y) - I(x, y);
  std::vector<Crop> chosen;
  for (int k = 0; k < count; ++k) {
    Crop best;
    best.score = -1;
    for (int y = 0; y + size <= h; y += 2)
      for (int x = 0; x + size <= w; x += 2) {
        bool overlaps = false;
        for (const Crop& c : chosen)
          overlaps |= x < c.x + c.size && c.x < x + size && y < c.y + c.size && c.y < y + size;
        if (overlaps) continue;
        double s = I(x + size, y + size) - I(x, y + size) - I(x + size, y) + I(x, y);
        if (s > best.score) best = Crop{x, y, size, s};
      }
    if (best.score < 0) break;
    best.score /= double(size) * double(size);
    chosen.push_back(best);
  }
  return chosen;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

json machine() {
  struct utsname u {};
  uname(&u);
  return {{"cpu", cpuModel()}, {"cores", int(std::thread::hardware_concurrency())},
          {"os", std::string(u.sysname) + " " + u.release + " " + u.machine}};
}

double valueAt(const std::map<int, double>& m, int f) {
  auto it = m.find(f);
  return it == m.end() ? kNaN : it->second;
}

// The pictures a run into `out` listed in `record` (its results.json: its crops' frames, its methods'
// maps and full images), so that a shorter run, or one with fewer methods, does not leave them beside
// its own. Only those: anything else in the folder is left alone, and a listed path that leads out
// of out/images is ignored.
void removePicturesListedIn(const fs::path& out, const fs::path& record) {
  const json last = readJson(record, false);
  if (!last.is_object() || !last.contains("scenes") || !last["scenes"].is_array()) return;
  std::error_code ec;
  const fs::path images = fs::weakly_canonical(out / "images", ec);
  if (ec) return;
  auto remove = [&](const fs::path& relative) {
    // Resolved (symbolic links and '..' followed), so a listed path can only reach a file under images/.
    std::error_code bad;
    const fs::path p = fs::weakly_canonical(out / relative, bad);
    if (bad) return;
    const auto [end, _] = std::mismatch(images.begin(), images.end(), p.begin(), p.end());
    if (end == images.end() && p != images && p.extension() == ".png") fs::remove(p, ec);
  };
  for (const json& scene : last["scenes"]) {
    if (!scene.is_object()) continue;
    for (const json& crop : scene.value("crops", json::array()))
      if (crop.is_object() && crop.contains("files") && crop["files"].is_object())
        for (const auto& [name, files] : crop["files"].items())
          if (files.is_array())
            for (const json& f : files)
              if (f.is_string()) remove(f.get<std::string>());
    std::vector<std::string> names = {"reference"};
    for (const char* list : {"methods", "eevee_curve"})
      for (const json& m : scene.value(list, json::array()))
        if (m.is_object() && m.contains("name") && m["name"].is_string()) names.push_back(m["name"]);
    for (const std::string& name : names) {
      remove(fs::path("images") / "full" / (name + ".png"));
      for (const char* map : {"_error", "_ssim", "_perceptual", "_temporal"})
        remove(fs::path("images") / "maps" / (name + map + ".png"));
    }
    remove(fs::path("images") / "maps" / "geometric_edges.png");
  }
  // The crop folders left empty (c<k>/<name>/, c<k>/), deepest first.
  std::vector<fs::path> folders;
  for (auto it = fs::recursive_directory_iterator(images / "crops", ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec))
    if (it->is_directory(ec)) folders.push_back(it->path());
  for (auto f = folders.rbegin(); f != folders.rend(); ++f)
    if (fs::is_empty(*f, ec)) fs::remove(*f, ec);
}

// The last run's report and pictures, withdrawn before this run changes a file they show (the methods'
// frames, then the pictures): a run stopped or failing halfway leaves no report at all rather than one
// linking missing or newer files. The report goes first; results.json, the list of the pictures, is
// renamed out of the way at once (a reader never finds it without its pictures) and removed only after
// them, so a run stopped in between leaves the list for the next run to finish the job.
void withdrawLastReport(const fs::path& out) {
  std::error_code ec;
  fs::remove(out / "report.html", ec);
  fs::remove(out / "results.csv", ec);
  const fs::path withdrawn = out / ".results_withdrawn.json";
  if (fs::exists(withdrawn, ec)) removePicturesListedIn(out, withdrawn);  // left by a run stopped here
  if (fs::exists(out / "results.json", ec)) {
    fs::rename(out / "results.json", withdrawn, ec);
    if (ec) ioError("cannot withdraw the last report's '" + (out / "results.json").string() + "': " + ec.message());
    removePicturesListedIn(out, withdrawn);
  }
  fs::remove(withdrawn, ec);
}

json figuresJson(const Entry& e, const EdgeFigures& x, int meanFrom) {
  json frames = json::array();
  for (const FrameFigures& f : e.frames) {
    const double geo = valueAt(x.geometryS, f.frame);
    frames.push_back({{"frame", f.frame}, {"psnr", f.psnr}, {"ssim", f.ssim}, {"perceptual_error", f.flip},
                      {"rmse", f.rmse}, {"temporal_error", f.temporalError}, {"render_s", f.renderS},
                      {"filter_s", f.filterS},
                      {"time_s", f.renderS + (std::isfinite(f.filterS) ? f.filterS : 0.0) + (std::isfinite(geo) ? geo : 0.0)},
                      {"psnr_geometric_edges", valueAt(x.edgePsnr, f.frame)}, {"geometry_render_s", geo},
                      {"file", f.file}});
  }
  std::vector<double> edge, geo;
  for (const auto& kv : x.edgePsnr)
    if (kv.first >= meanFrom) edge.push_back(kv.second);
  for (const auto& kv : x.geometryS) geo.push_back(kv.second);
  json j = {{"name", e.name}, {"kind", e.kind}, {"samples", e.samples}, {"input", e.inputSet},
            {"temporal", e.temporal}, {"panel", e.panel}, {"error", e.error.empty() ? json(nullptr) : json(e.error)},
            {"mean", {{"psnr", e.psnr}, {"ssim", e.ssim}, {"perceptual_error", e.flip},
                      {"temporal_error", e.temporalError}, {"time_s", e.timeS}, {"render_s", e.renderS},
                      {"filter_s", e.filterS}, {"psnr_geometric_edges", mean(edge)},
                      {"geometry_render_s", median(geo)}}},
            {"equivalent_eevee_samples", e.equivalentSamples},
            {"equivalent_note", e.equivalentNote}, {"pareto", e.pareto}, {"frames", frames}};
  if (e.kind == "eevee") {  // the flat shape for curve points
    j["psnr"] = e.psnr;
    j["ssim"] = e.ssim;
    j["perceptual_error"] = e.flip;
    j["temporal_error"] = e.temporalError;
    j["time_s"] = e.timeS;
  }
  return j;
}

std::string csvNumber(double v) {
  if (!std::isfinite(v)) return "";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// A text field as RFC 4180 has it: quoted (quotes doubled) when it holds a comma, a quote or a line
// break, as a scene named after its .blend may.
std::string csvText(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

}  // namespace

double equivalentSamples(const std::vector<int>& samples, const std::vector<double>& psnr, double value,
                         std::string* note) {
  if (note) note->clear();
  if (samples.empty() || !std::isfinite(value)) return kNaN;
  for (std::size_t i = 0; i + 1 < samples.size(); ++i) {
    double a = psnr[i], b = psnr[i + 1];
    if ((value >= a && value <= b) || (value <= a && value >= b)) {
      double t = b == a ? 0.0 : (value - a) / (b - a);
      return std::exp2(std::log2(double(samples[i])) * (1 - t) + std::log2(double(samples[i + 1])) * t);
    }
  }
  if (samples.size() == 1 && value == psnr[0]) return samples[0];
  double best = *std::max_element(psnr.begin(), psnr.end());
  if (note) *note = value > best ? "> " + std::to_string(samples.back()) : "< " + std::to_string(samples.front());
  return kNaN;
}

int run(const Options& o) {
  const auto tStart = Clock::now();
  const fs::path out(o.outDir), renders(o.renderDir);
  json scene = readJson(renders / "scene.json", true);
  const int first = scene["frames"][0], last = scene["frames"][1];
  std::vector<int> frames;
  for (int f = first; f <= last; ++f) frames.push_back(f);
  if (o.warmup >= int(frames.size()))
    throw Exception(CRISP_ERROR_INVALID_ARGUMENT,
                    "--warmup " + std::to_string(o.warmup) + " leaves none of the " + std::to_string(frames.size()) +
                        " frames (" + std::to_string(first) + "-" + std::to_string(last) + ") to measure");
  const int meanFrom = first + o.warmup;  // the error means start here (Options::warmup)
  const int width = scene["resolution"][0], height = scene["resolution"][1];
  const int refSamples = scene["reference_samples"];
  const std::vector<int> curveSamples = scene["curve"].get<std::vector<int>>();
  const fs::path refDir = renders / ("reference_" + std::to_string(refSamples));
  const fs::path oneSample = renders / "eevee_1";
  const json facts = scene.value("facts", json::object());
  const bool moving = facts.value("camera_moves", false) || !facts.value("moving_objects", json::array()).empty() ||
                      !facts.value("deforming_objects", json::array()).empty();

  // Entries: the methods (none first), Blender's SMAA, then the curve.
  std::vector<Entry> methods, curve;
  for (const std::string& m : o.methods) {
    Entry e;
    e.name = m;
    const MethodSpec spec = parseMethodSpec(m);
    e.method = spec.method;
    e.kind = "method";
    e.panel = o.panel.is_object() && o.panel.value("row", json()) == json(m);
    std::string set = scene["inputs"].value(e.method, std::string("eevee_1"));
    e.inputSet = set;
    const json& plan = scene["plans"].contains(e.method) ? scene["plans"][e.method] : json::object();
    e.temporal = plan.value("jitter", false);
    if (plan.contains("params") && plan["params"].is_object())
      for (const auto& [key, value] : plan["params"].items()) {
        if (spec.gives(key)) continue;
        e.planParams.emplace_back(key, value.is_string() ? value.get<std::string>() : value.dump());
        // Said under --quiet too: it changes what the row measures.
        std::fprintf(stderr, "crisp eval: %s runs with %s=%s, as its plan for this scene asks (%s)\n", m.c_str(),
                     key.c_str(), e.planParams.back().second.c_str(),
                     plan.value("history_note", std::string("the scene's plan")).c_str());
      }
    if (plan.contains("passes") && plan["passes"].is_array()) {
      const json& passes = plan["passes"];
      e.subsamplesRendered = std::find(passes.begin(), passes.end(), "subsamples") != passes.end();
    }
    methods.push_back(e);
  }
  {
    Entry e;
    e.name = e.method = "blender-smaa";
    e.kind = "blender";
    e.inputSet = "eevee_1";
    methods.push_back(e);
  }
  for (int s : curveSamples) {
    Entry e;
    e.name = e.method = "eevee-" + std::to_string(s);
    e.kind = "eevee";
    e.samples = s;
    e.inputSet = "eevee_" + std::to_string(s);
    curve.push_back(e);
  }

  withdrawLastReport(out);

  cli::StopNotice stopNotice("crisp eval");
  // 1. Run the library methods, frames in order, each in a child process so that a method that
  // crashes is reported in the page instead of taking the evaluation down. Nothing in this process
  // has used the thread pool yet, so each child starts its own.
  for (Entry& e : methods) {
    if (e.kind != "method") continue;
    stopNotice.step("while it ran method '" + e.name + "': the frames made are kept in " + (out / "methods").string() +
                    ", and the same command goes on from them");
    const fs::path errorFile = out / "methods" / e.name / "error.txt";
    std::error_code ec;
    fs::remove(errorFile, ec);
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t parent = getpid();
    // The stop signals wait while the child is made and takes the previous handlers back: one that came
    // in between would have it say the parent's line too.
    const sigset_t held = cli::StopNotice::hold();
    pid_t pid = fork();
    if (pid != 0) cli::StopNotice::release(held);
    if (pid < 0) ioError("cannot run method '" + e.name + "' (fork failed)");
    if (pid == 0) {
      // crisp stopped (kill PID, a farm cancelling its task) or killed outright: the method stops with it
      // (its temporary files removed by their signal handler) rather than going on alone, writing into the
      // folder, as Blender does (cli/blender.cpp).
      cli::StopNotice::restore();
      cli::StopNotice::release(held);
      prctl(PR_SET_PDEATHSIG, SIGTERM);
      if (getppid() != parent) _exit(1);  // crisp died before that
      int code = 0;
      try {
        cli::Progress progress("method " + e.name, int(frames.size()), o.quiet);
        runMethod(e, o, frames, renders / e.inputSet, moving, progress);
      } catch (const std::exception& ex) {
        try {
          cli::makeDirectories(errorFile.parent_path().string());
          cli::writeTextFile(errorFile.string(), ex.what());
        } catch (...) {
        }
        code = 1;
      }
      std::fflush(nullptr);
      _exit(code);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (WIFSIGNALED(status)) {
      e.error = std::string("crashed (signal ") + std::to_string(WTERMSIG(status)) + ": " + strsignal(WTERMSIG(status)) + ")";
    } else if (WEXITSTATUS(status) != 0) {
      std::ifstream in(errorFile);
      std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      e.error = text.empty() ? "failed (exit " + std::to_string(WEXITSTATUS(status)) + ")" : text;
    }
    if (!e.error.empty())
      std::fprintf(stderr, "crisp: method '%s' failed (reported in the page): %s\n", e.name.c_str(), e.error.c_str());
  }

  stopNotice.step("while it measured: the methods' frames are kept, and the same command measures them again");
  // 2. Measure. Every image is read once per entry; the reference frames are kept.
  std::map<int, Image> refs;
  for (int f : frames) refs[f] = readFrame((refDir / frameName(f)).string()).pass("color");

  // W and the disocclusion mask (warpGeometry).
  std::map<int, Image> motions, masks;
  std::string warp = "identity: nothing moves over the frames";
  if (moving) {
    WarpGeometry g = warpGeometry(renders, scene, frames, o);
    if (g.description.empty()) {
      warp = "identity: the scene moves but no motion vectors were available (the temporal error overstates)";
    } else {
      motions = std::move(g.motions);
      masks = std::move(g.masks);
      warp = g.description + " (renderer or reconstructed); valid = inside the previous frame and not disoccluded " +
             (masks.empty() ? std::string("(no depth or IDs: every pixel inside)")
              : g.idsUnusable.empty() ? std::string("(object ID / depth test)")
                                      : "(depth test; object IDs not used: " + g.idsUnusable + ")");
    }
  }
  // A cut to another camera (a timeline marker): nothing on screen continues the frame before, and the
  // temporal methods start over there, so its temporal error is not measured (as the first frame's).
  std::set<int> cuts;
  for (const json& c : facts.value("camera_cuts", json::array()))
    if (c.is_number_integer()) cuts.insert(c.get<int>());
  if (!cuts.empty()) {
    std::string list;
    for (int c : cuts) list += (list.empty() ? "" : ", ") + std::to_string(c);
    warp += "; not measured at the camera cuts (frames " + list + ")";
  }

  // Geometric-edge pixels (geometricEdgeMask) where some method's input set has the geometric
  // sub-samples (rsaa): the PSNR over them is a figure of every entry.
  std::map<int, Image> edgeMasks;
  std::string edgeNote = "no method rendered geometric sub-samples (rsaa), so no geometric-edge figures";
  std::set<std::string> geometrySets;
  for (const Entry& e : methods) {
    const json plan = scene["plans"].value(e.method, json::object());
    const json passes = plan.value("passes", json::array());
    if (std::find(passes.begin(), passes.end(), "subsamples") != passes.end()) geometrySets.insert(e.inputSet);
  }
  if (!geometrySets.empty()) {
    const fs::path dir = renders / *geometrySets.begin();
    try {
      for (int f : frames) {
        Frame fr = readFrame((dir / frameName(f)).string());
        attachSubsamples(fr, sidecarPathFor(fr.path));
        Image m = geometricEdgeMask(fr);
        double n = 0;
        for (float v : m.data) n += v;
        if (n > 0) edgeMasks[f] = std::move(m);
      }
      edgeNote = "pixels whose 9 geometric samples (centre + the 8 rsaa sub-samples of " + dir.filename().string() +
                 ") do not all lie on the centre's surface: background vs geometry, planar depth differing by "
                 "more than 5 %, or normals more than 20 degrees apart";
    } catch (const std::exception& ex) {
      edgeMasks.clear();
      edgeNote = std::string("no geometric-edge figures: ") + ex.what();
      std::fprintf(stderr, "crisp: %s\n", edgeNote.c_str());
    }
  }
  std::map<std::string, EdgeFigures> edgeFigures;

  // The middle frame of those the error means cover: the images and maps shown beside the headline are
  // of a frame it measures, not of the warm-up (--warmup 15 of 16: frame 16, not 9).
  const int mapFrame = frames[std::size_t(o.warmup) + (frames.size() - std::size_t(o.warmup)) / 2];
  Image errorSum(width, height, 1);  // the 1-sample frames' squared error, summed over errorFrames frames
  int errorFrames = 0;
  const fs::path images = out / "images";
  cli::makeDirectories((images / "full").string());
  cli::makeDirectories((images / "maps").string());
  if (edgeMasks.count(mapFrame)) {
    Image rgb(width, height, 3);
    for (std::size_t i = 0; i < edgeMasks[mapFrame].data.size(); ++i)
      for (int c = 0; c < 3; ++c) rgb.data[3 * i + std::size_t(c)] = edgeMasks[mapFrame].data[i];
    writeImage((images / "maps" / "geometric_edges.png").string(), rgb);
  }
  std::map<std::string, std::map<int, Image>> kept;  // entry -> frame -> colour, for the crops
  {
    int total = int((methods.size() + curve.size()) * frames.size());
    cli::Progress progress("measure", total, o.quiet);
    auto measure = [&](Entry& e) {
      std::map<int, double> renderS = sameWorkRenderTimes(renders, scene, e.inputSet);
      std::map<int, double> filterS;
      fs::path dir;
      if (e.kind == "method") {
        dir = out / "methods" / e.name;
        json t = readJson(dir / "times.json", false);
        for (auto it = t.begin(); it != t.end(); ++it) filterS[std::stoi(it.key())] = it.value().get<double>();
      } else if (e.kind == "blender") {
        dir = renders / "blender-smaa";
        filterS = renderTimes(dir);
      } else {
        dir = renders / e.inputSet;
      }
      Image previous;
      Image temporalSum;  // per-pixel temporal error summed over frames (methods' maps)
      int temporalFrames = 0;
      for (int f : frames) {
        FrameFigures ff;
        ff.frame = f;
        ff.renderS = renderS.count(f) ? renderS[f] : kNaN;
        ff.filterS = e.kind == "eevee" ? 0.0 : (filterS.count(f) ? filterS[f] : kNaN);
        fs::path file = dir / frameName(f);
        ff.file = fs::relative(file, out).string();
        if (!e.error.empty() || !fs::exists(file)) {
          e.frames.push_back(ff);
          progress.step(e.name + " frame " + std::to_string(f));
          continue;
        }
        Image test = readFrame(file.string()).pass("color");
        if (cuts.count(f)) previous = Image();  // no temporal error across a cut
        Image err, ssim, flip;
        MetricMaps maps;
        bool wantMaps = f == mapFrame && e.kind != "eevee";
        if (e.name == "none" || wantMaps) maps.error = &err;
        if (wantMaps) maps.ssim = &ssim, maps.flip = &flip;
        Metrics m;
        try {
          m = compareImages(refs[f], test, nullptr, maps, o.threads);
        } catch (const Exception& ex) {
          throw Exception(ex.code(), "comparing '" + file.string() + "' with the reference '" +
                                         (refDir / frameName(f)).string() + "': " + ex.what());
        }
        ff.psnr = m.psnr, ff.ssim = m.ssim, ff.flip = m.flip, ff.rmse = m.rmse;
        if (edgeMasks.count(f)) {
          CompareOptions cheap;
          cheap.ssim = cheap.flip = false;
          edgeFigures[e.name].edgePsnr[f] = compareImages(refs[f], test, &edgeMasks[f], {}, o.threads, cheap).psnr;
        }
        if (e.kind == "method" && geometrySets.count(e.inputSet) && e.method == "rsaa")
          edgeFigures[e.name].geometryS[f] = geometryRenderSeconds(renders / e.inputSet / frameName(f));
        if (e.name == "none") {
          for (std::size_t i = 0; i < errorSum.data.size(); ++i) errorSum.data[i] += err.data[i];
          ++errorFrames;
        }
        if (wantMaps) {
          writeImage((images / "full" / (e.name + ".png")).string(), test);
          writeMap(images / "maps" / (e.name + "_error.png"), err, errorScale);
          writeMap(images / "maps" / (e.name + "_ssim.png"), ssim, ssimScale);
          writeMap(images / "maps" / (e.name + "_perceptual.png"), flip, flipScale);
        }
        if (!previous.empty()) {
          int prevFrame = f - 1;
          const Image* motion = motions.count(f) ? &motions[f] : nullptr;
          const Image* mask = masks.count(f) ? &masks[f] : nullptr;
          Image teMap;
          ff.temporalError = temporalError(test, previous, refs[f], refs[prevFrame], motion, mask, o.threads,
                                           e.kind != "eevee" ? &teMap : nullptr)
                                 .value;
          if (!teMap.empty()) {
            if (temporalSum.empty()) temporalSum = Image(teMap.width, teMap.height, 1);
            for (std::size_t i = 0; i < teMap.data.size(); ++i) temporalSum.data[i] += teMap.data[i];
            ++temporalFrames;
          }
        }
        if (e.kind != "eevee") kept[e.name][f] = test;
        previous = std::move(test);
        e.frames.push_back(ff);
        progress.step(e.name + " frame " + std::to_string(f));
      }
      if (temporalFrames > 0) {  // mean over the frames measured
        for (float& v : temporalSum.data) v /= float(temporalFrames);
        writeMap(images / "maps" / (e.name + "_temporal.png"), temporalSum, temporalScale);
      }
      std::vector<double> p, s, fl, te, rs, fs_, ts;
      for (const FrameFigures& ff : e.frames) {
        if (ff.frame >= meanFrom)  // the warm-up's errors are listed, not averaged
          p.push_back(ff.psnr), s.push_back(ff.ssim), fl.push_back(ff.flip), te.push_back(ff.temporalError);
        rs.push_back(ff.renderS), fs_.push_back(ff.filterS);  // a frame's cost is the same in the warm-up
      }
      e.psnr = mean(p), e.ssim = mean(s), e.flip = mean(fl), e.temporalError = mean(te);
      // Times: the median over frames, so a burst of load from other processes on a shared machine
      // does not move a whole figure (every per-frame time is in the results too).
      e.renderS = median(rs), e.filterS = median(fs_);
      e.timeS = e.renderS + (std::isfinite(e.filterS) ? e.filterS : 0.0);
      {  // rsaa's 8 geometry renders are part of its cost per frame (reported apart too)
        std::vector<double> geo;
        for (const auto& kv : edgeFigures[e.name].geometryS) geo.push_back(kv.second);
        const double g = median(geo);
        if (std::isfinite(g)) e.timeS += g;
      }
      if (e.error.empty() && !std::isfinite(e.psnr)) e.error = "no output frames to measure";
      if (!e.error.empty()) e.timeS = e.filterS = kNaN;  // a failed method has no time per frame
    };
    for (Entry& e : methods) measure(e);
    for (Entry& e : curve) measure(e);
  }
  writeImage((images / "full" / "reference.png").string(), refs[mapFrame]);

  // 3. Equivalent EEVEE samples and the Pareto front (time down, PSNR up) over methods and curve.
  std::vector<int> cs;
  std::vector<double> cp;
  for (const Entry& e : curve)
    if (std::isfinite(e.psnr)) cs.push_back(e.samples), cp.push_back(e.psnr);
  for (Entry& e : methods) e.equivalentSamples = equivalentSamples(cs, cp, e.psnr, &e.equivalentNote);
  for (Entry& e : curve) e.equivalentSamples = e.samples;
  std::vector<Entry*> all;
  for (Entry& e : methods) all.push_back(&e);
  for (Entry& e : curve) all.push_back(&e);
  for (Entry* a : all) {
    if (!std::isfinite(a->psnr) || !std::isfinite(a->timeS)) continue;
    a->pareto = true;
    for (Entry* b : all)
      if (b != a && std::isfinite(b->psnr) && std::isfinite(b->timeS) && b->timeS <= a->timeS &&
          b->psnr >= a->psnr && (b->timeS < a->timeS || b->psnr > a->psnr))
        a->pareto = false;
  }

  // 4. Crops at the most aliased places, every frame, for the page and its flip-book.
  if (errorFrames > 0)  // a mean per frame, so the crops' score does not grow with the run's length
    for (float& v : errorSum.data) v /= float(errorFrames);
  std::vector<Crop> crops = chooseCrops(errorSum, 3);
  json cropsJson = json::array();
  std::vector<std::string> cropEntries = {"reference"};
  for (const Entry& e : methods)
    if (kept.count(e.name)) cropEntries.push_back(e.name);
  for (std::size_t k = 0; k < crops.size(); ++k) {
    const Crop& c = crops[k];
    json files = json::object();
    for (const std::string& name : cropEntries) {
      fs::path dir = images / "crops" / ("c" + std::to_string(k)) / name;
      cli::makeDirectories(dir.string());
      json list = json::array();
      for (int f : frames) {
        const Image* src = name == "reference" ? &refs[f] : (kept[name].count(f) ? &kept[name][f] : nullptr);
        if (!src) continue;
        fs::path p = dir / frameName(f, ".png");
        writeImage(p.string(), crop(*src, c));
        list.push_back(fs::relative(p, out).string());
      }
      files[name] = list;
    }
    cropsJson.push_back({{"x", c.x}, {"y", c.y}, {"size", c.size}, {"score", c.score}, {"files", files}});
  }

  // 5. Results.
  json methodsJson = json::array(), curveJson = json::array();
  for (const Entry& e : methods) methodsJson.push_back(figuresJson(e, edgeFigures[e.name], meanFrom));
  for (const Entry& e : curve) curveJson.push_back(figuresJson(e, edgeFigures[e.name], meanFrom));
  json refFiles = json::array();
  for (int f : frames) refFiles.push_back(fs::relative(refDir / frameName(f), out).string());
  std::map<int, double> refTimes = renderTimes(refDir);
  std::vector<double> rt;  // this run's frames (the folder may hold others), a median as every time here
  for (int f : frames)
    if (refTimes.count(f)) rt.push_back(refTimes[f]);
  json sceneJson = {
      {"name", scene.value("scene_label", scene.value("scene", std::string("scene")))},
      {"blender_scene", scene.value("scene", std::string())},
      {"resolution", {width, height}},
      {"frames", {first, last}},
      {"means_over_frames", {meanFrom, last}},  // the error means; times are medians over every frame
      {"reference", {{"samples", refSamples}, {"time_s", median(rt)}, {"files", refFiles}}},
      {"methods", methodsJson},
      {"eevee_curve", curveJson},
      {"temporal_error_warp", warp},
      {"geometric_edges", {{"definition", edgeNote}, {"frames_with_edges", int(edgeMasks.size())}}},
      {"smaa", scene.value("smaa", json::object())},
      {"plans", scene.value("plans", json::object())},
      {"facts", facts},
      {"jitter_distribution", scene.value("jitter_distribution", std::string())},
      // What came from the .blend's Crisp panel (its method and parameters: the row "row" names; its jitter).
      {"panel", o.panel},
      // Film > Filter Size (px): the jitter's spread, EEVEE's pixel filter (the reference's, the
      // curve's) and the temporal methods' filterSize unless their settings give one (runMethod).
      {"filter_size", scene.value("filter_size", json())},
      {"map_frame", mapFrame},
      {"crops", cropsJson},
      {"images", {{"full", "images/full"}, {"maps", "images/maps"}}},
  };
  char crispVersion[32];
  std::snprintf(crispVersion, sizeof crispVersion, "%d.%d.%d", CRISP_VERSION_MAJOR, CRISP_VERSION_MINOR,
                CRISP_VERSION_PATCH);
  double evalSeconds = std::chrono::duration<double>(Clock::now() - tStart).count();
  json results = {
      {"command", o.command},
      {"versions", {{"crisp", crispVersion}, {"blender", scene.value("blender_version", std::string())},
                    {"oiio", OIIO_VERSION_STRING}}},
      {"machine", machine()},
      {"threads", o.threads},
      {"run_seconds", {{"blender", o.blenderSeconds}, {"methods_and_measures", evalSeconds}}},
      {"metrics_note", "PSNR, SSIM, perceptual error (FLIP-style) and temporal error on display-encoded values "
                       "(linear RGB clamped to [0,1], sRGB-encoded), means over the frames means_over_frames gives (PSNR: the "
                       "mean of the per-frame dB); time per frame = 1-sample render + filter "
                       "(+ rsaa's geometry renders, also given apart as geometry_render_s), each the median over frames; "
                       "render sets of the same samples and passes (eevee_1 and a colour-only jittered set) are timed as "
                       "one, each frame's render_s the mean of their times; SSIM: Wang et al. 2004 (11x11 Gaussian, "
                       "sigma 1.5) of the luma, the image mirrored at its borders"},
      {"scenes", json::array({sceneJson})},
  };
  writeJson(out / "results.json", results);

  std::ostringstream csv;
  // The same figures as results.json (figuresJson): its "mean" and per-frame entries, one row each.
  csv << "scene,kind,name,frame,psnr,ssim,perceptual_error,temporal_error,render_s,filter_s,geometry_render_s,"
         "time_s,equivalent_eevee_samples,equivalent_note,error\n";
  // equivalent: the number (empty outside the curve) and the note ("> 16"), in columns of their own.
  auto row = [&](const Entry& e, const std::string& frame, const json& f, const std::string& equivalent) {
    std::string err = e.error;
    std::replace(err.begin(), err.end(), '"', '\'');
    auto number = [&](const char* key) { return csvNumber(f.value(key, json()).is_number() ? f[key].get<double>() : kNaN); };
    csv << csvText(sceneJson["name"].get<std::string>()) << "," << e.kind << "," << e.name << "," << frame;
    for (const char* key : {"psnr", "ssim", "perceptual_error", "temporal_error", "render_s", "filter_s",
                            "geometry_render_s", "time_s"})
      csv << "," << number(key);
    csv << "," << equivalent << ",\"" << err << "\"\n";
  };
  for (const auto& [list, results] : {std::pair{&methods, &methodsJson}, std::pair{&curve, &curveJson}})
    for (std::size_t k = 0; k < list->size(); ++k) {
      const Entry& e = (*list)[k];
      const json& j = (*results)[k];
      row(e, "mean", j["mean"], csvNumber(e.equivalentSamples) + "," + e.equivalentNote);
      for (const json& f : j["frames"]) row(e, std::to_string(f["frame"].get<int>()), f, ",");
    }
  cli::writeTextFile((out / "results.csv").string(), csv.str());
  writeReport(o.outDir, results);
  return 0;
}

}  // namespace crisp::eval
