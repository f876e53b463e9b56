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

// EncodePng into `path` through AtomicWrite (temp file + rename).
void WritePng(cairo_surface_t* image, const std::string& path);

// Attaches the surface's PNG encoding as its CAIRO_MIME_TYPE_PNG data, which cairo's SVG
// surface embeds as is instead of encoding the raster itself.
void AttachPng(cairo_surface_t* image, const std::string& what);

}  // namespace furnihost::app
