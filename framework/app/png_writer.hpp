// PNG encoding of cairo image surfaces for the plots, fast: cairo's own writer (libpng defaults:
// zlib level 6, adaptive filters) spent ~50 ms per plot on a 1000 x 1000 px bird's-eye view,
// more than the ScanNet route's recognition stage.
#pragma once
#include <cairo.h>

#include <string>
#include <vector>

namespace furnihost::app {

// The pixels of an ARGB32 or RGB24 image surface as a PNG (RGBA, un-premultiplied as cairo's
// writer does; RGB for RGB24), zlib level 1 and the "sub" filter. Throws InputError naming
// `what` when libpng fails.
std::vector<unsigned char> EncodePng(cairo_surface_t* image, const std::string& what);

// The pixels of an image surface, read once on the thread that owns it: EncodePixels needs no
// cairo call, so it may run on another thread while the surface is left alone or only read
// (as the source of a paint).
struct Pixels {
  const unsigned char* data = nullptr;
  int width = 0, height = 0, stride = 0;
  bool alpha = false;
};
// Flushes `image` and describes its pixels; throws InputError naming `what` when it is not an
// ARGB32 or RGB24 image surface.
Pixels PixelsOf(cairo_surface_t* image, const std::string& what);
std::vector<unsigned char> EncodePixels(const Pixels& pixels, const std::string& what);

// `bytes` into `path` through AtomicWrite (temp file + rename).
void WriteBytes(const std::vector<unsigned char>& bytes, const std::string& path);

// EncodePng into `path` through AtomicWrite (temp file + rename).
void WritePng(cairo_surface_t* image, const std::string& path);

// Attaches `png`, the surface's PNG encoding (EncodePixels of its pixels), as its
// CAIRO_MIME_TYPE_PNG data, which cairo's SVG surface embeds as is instead of encoding the raster
// itself.
void AttachPng(cairo_surface_t* image, std::vector<unsigned char> png, const std::string& what);

}  // namespace furnihost::app
