// SPDX-License-Identifier: Apache-2.0
// Base class of every filter: named image roles, named typed parameters,
// commit (validate + allocate) and execute (one frame, no allocation).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/context.h"
#include "core/image.h"
#include "core/params.h"

namespace crisp {

struct ImageRole {
  const char* name;
  bool required;
  int minChannels;
  int maxChannels;
  bool isUint;     // the object-ID role
  const char* meaning;
};

class Filter {
 public:
  Filter(Context& context, std::vector<ParamSpec> params, std::vector<ImageRole> roles);
  virtual ~Filter();
  Filter(const Filter&) = delete;
  Filter& operator=(const Filter&) = delete;

  virtual const char* type() const = 0;

  void setImage(const std::string& role, const ImageView& view);
  void unsetImage(const std::string& role);
  bool hasImage(const std::string& role) const;
  const ImageView& image(const std::string& role) const;

  // Parameter setters mark the filter as needing a commit; `what` names the
  // change ("parameter 'x' was set") for execute's error until that commit.
  ParamSet& params() { return params_; }
  const ParamSet& params() const { return params_; }
  void markDirty(const std::string& what);
  bool committed() const { return committed_; }

  void commit();
  void execute();
  virtual void reset() {}

  const std::vector<ImageRole>& roles() const { return roles_; }
  std::string doc() const;
  // {"type", "images": [{"name", "required", "minChannels", "maxChannels", "uint", "meaning"}], "params": ParamSet::json()}
  std::string infoJson() const;
  int width() const { return width_; }
  int height() const { return height_; }
  int numThreads() const { return context_.numThreads(); }
  Context& context() { return context_; }

  std::atomic<int> refCount{1};

 protected:
  virtual void onCommit() = 0;   // params_ and images are valid; allocate here
  virtual void onExecute() = 0;  // run one frame
  // False for an image that is set but superseded by another (rsaa's sub0..sub7
  // when 'subsamples' is set): commit neither checks nor reads it.
  virtual bool readsImage(const std::string& role) const { return true; }

  // Copies "color" into a packed RGBA float image, sanitising non-finite
  // values (conventions.h); alpha is 1 where the input has 3 channels.
  void stageColor(Image& rgba) const;
  // Writes a packed RGBA image to the "output" view (3 or 4 channels).
  void writeOutput(const Image& rgba) const;
  // The input image `role`, or a packed copy of it (kept for the next frames) when the output
  // shares its memory: for kernels that read an input's neighbours after other rows of the
  // output are written, so that in-place use gives the same result as separate buffers.
  ImageView inputApartFromOutput(const std::string& role);

 private:
  Context& context_;
  ParamSet params_;
  std::vector<ImageRole> roles_;
  std::map<std::string, ImageView> images_;
  std::map<std::string, std::vector<float>> apartCopies_;  // inputApartFromOutput's copies
  bool committed_ = false;
  bool everCommitted_ = false;
  bool commitFailed_ = false;  // the last commit threw
  std::string firstChange_;  // markDirty's `what` since the last commit
  int width_ = 0;
  int height_ = 0;
};

// Registry: the filters known by name.
std::unique_ptr<Filter> createFilter(Context& context, const std::string& type);
const std::vector<std::string>& filterTypes();
const char* filterTypesJoined();
bool isFilterType(const std::string& name);

}  // namespace crisp
