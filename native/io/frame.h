// SPDX-License-Identifier: Apache-2.0
// A frame's render passes read from disk, converted to conventions.h.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/image.h"

namespace crisp {

// Roles a frame can hold, with their channel counts in memory:
//   color  4  (Combined RGBA, or a plain RGB(A) image; alpha 1 if absent)
//   depth  1  (Depth.Z)
//   normal 3  (Normal.XYZ)
//   motion 4  (Vector.XYZW, converted to y down)
//   id     1  uint (CryptoObject00.r bits; the rank-0 object of each pixel)
//   albedo 3  (DiffCol.RGB)
// Where a frame sits in its file, in OpenEXR's terms (pixel coordinates, y down): the display
// window, whose size is the frame's, and the data window of the colour pass, which may be offset
// from it, smaller or larger. An image without windows (PNG) has both at origin 0, the frame's size.
struct FrameWindows {
  int displayX = 0, displayY = 0;  // display window origin; its size is the frame's
  int dataX = 0, dataY = 0, dataWidth = 0, dataHeight = 0;
};

struct Frame {
  std::string path;
  int width = 0;
  int height = 0;
  FrameWindows windows;  // the file's; writeImage(path, image, windows) writes the output back into them
  std::map<std::string, Image> passes;
  std::map<std::string, std::uint32_t> objectIds;  // Cryptomatte manifest: name -> hash
  // Every channel in the file (in every part), by the name it is matched by: as named there, or
  // completed by its part's name (frame_read.cpp, matchName).
  std::vector<std::string> channelNames;
  // Colour values (RGBA) that were NaN or +-Inf in the file; the colour pass
  // holds them sanitised (NaN -> 0, +-Inf -> +-65504, conventions.h).
  long nonFiniteColour = 0;
  // Finite colour values beyond +-65504 in the file, which the colour pass holds clamped to it.
  long clampedColour = 0;
  // Passes the file holds in a form that cannot be used, and why (an ID pass
  // stored as half float): an error only for a method that reads them.
  std::map<std::string, std::string> unusable;
  // The parts of a multi-part EXR no pass was read from, which hold nothing read here:
  // "part 3 of 3 ('diffuse') (channels: diffuse.R, diffuse.G, diffuse.B)".
  std::vector<std::string> partsNotRead;
  // The view layer read ("" for a plain image) and the other view layers of a multilayer EXR, which
  // nothing is read from (readFrame reads one): "'B' (4 channels)". Blender's "Composite" layer
  // (the compositor's result, beside the view layer) is not listed.
  std::string layer;
  std::vector<std::string> layersNotRead;

  bool has(const std::string& role) const { return passes.count(role) != 0; }
  // Throws CRISP_ERROR_INVALID_DATA naming the file and the pass if absent
  // (saying why, when the file holds it unusable).
  const Image& pass(const std::string& role) const;
  std::string passList() const;  // "color,depth,..."
};

// Reads a Blender multilayer EXR or a plain RGB(A) EXR/PNG. Of a multi-part
// EXR each pass is read from the part holding it (frame_read.cpp says how they
// are found). Throws CRISP_ERROR_IO (unreadable, truncated, corrupt) or
// CRISP_ERROR_INVALID_DATA (no colour, inconsistent layers, a pass in two
// parts), always naming the file (and the part).
Frame readFrame(const std::string& path);
// CRISP_ERROR_IO naming the file unless `path` is a non-empty file this
// process may read (readFrame's first check; commands run it on every input
// before they write anything).
void checkReadable(const std::string& path);
// The same, reading the named view layer of a multilayer EXR (throws
// CRISP_ERROR_INVALID_DATA listing the layers if it is absent). readFrame(path)
// picks "ViewLayer" (Blender's default name) if present, else the first layer,
// by name, that has a Combined pass, else the plain R,G,B[,A] channels.
Frame readFrame(const std::string& path, const std::string& viewLayer);
// readFrame(path) without the colour's pixels (no "color" pass; the colour's
// part still sets the size and windows, and must be there): for files whose
// geometry passes alone are read, rsaa's sub-samples (Blender's 8-channel
// sub-sample file reads in about 40 % less CPU time).
Frame readGeometryFrame(const std::string& path);

// A mask image: its first channel, at the display window's size (0 outside
// the data window). A one-channel file's channel whatever its name ("R",
// "mask", "Depth.Z"); otherwise the first channel of readFrame's colour.
// Throws as readFrame, naming the file.
Image readMask(const std::string& path);

// The file type writeImage takes from `path`: its extension, lower case, with
// the dot (".exr"); "" without one.
std::string lowerExtension(const std::string& path);

// How an EXR's channels are stored, as Blender's Output properties say it
// (Color Depth, Codec). The default is Crisp's own: 32-bit float, ZIP.
struct ExrStorage {
  // 16-bit float channels. Finite values beyond half's range (+-65504) are
  // written as +-65504 rather than as infinities.
  bool half = false;
  std::string compression = "zip";  // one of exrCompressions()
};
// The codecs of Blender's OpenEXR output, by OpenEXR's names: none, zip, zips,
// piz, pxr24, rle, b44, b44a, dwaa, dwab.
const std::vector<std::string>& exrCompressions();
// Throws CRISP_ERROR_INVALID_ARGUMENT for a compression not in
// exrCompressions(), listing them.
void checkExrStorage(const ExrStorage& storage);

// Writes RGB(A) float to .exr (RGBA stored as `storage` says, alpha 1 if
// absent) or .png (8-bit sRGB-encoded RGBA; storage unused) by extension,
// through a temporary file in the same folder renamed into place: an existing
// file is replaced whole or not at all.
void writeImage(const std::string& path, const ImageView& image, const ExrStorage& storage = {});
void writeImage(const std::string& path, const Image& image);
// The same for an image that is a frame's display window (a filter's output),
// placed where `windows` says: an EXR gets the display window's origin and the
// colour's data window clipped to the display window (the pixels outside it,
// which the reader filled, are left out; the whole display window if the two
// do not overlap). A PNG, which has no windows, holds the whole image.
void writeImage(const std::string& path, const ImageView& image, const FrameWindows& windows,
                const ExrStorage& storage = {});

}  // namespace crisp
