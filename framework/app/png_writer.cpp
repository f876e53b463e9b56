#include "png_writer.hpp"

#include <png.h>

#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "furnihost/error.hpp"
#include "furnihost/host/io.hpp"

namespace furnihost::app {

namespace {
// libpng is C: its errors leave through longjmp to EncodePng's setjmp, never as exceptions.
struct ErrorSink {
  char message[256] = "";
};
void Append(png_structp png, png_bytep data, png_size_t n) {
  auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
  try {
    out->insert(out->end(), data, data + n);
  } catch (...) {
    png_error(png, "out of memory");
  }
}
void NoFlush(png_structp) {}
void Fail(png_structp png, png_const_charp msg) {
  auto* sink = static_cast<ErrorSink*>(png_get_error_ptr(png));
  std::snprintf(sink->message, sizeof sink->message, "%s", msg ? msg : "libpng error");
  png_longjmp(png, 1);
}
void Warn(png_structp, png_const_charp) {}
}  // namespace

Pixels PixelsOf(cairo_surface_t* image, const std::string& what) {
  cairo_surface_flush(image);
  const cairo_format_t format = cairo_image_surface_get_format(image);
  Pixels p;
  p.width = cairo_image_surface_get_width(image), p.height = cairo_image_surface_get_height(image);
  p.stride = cairo_image_surface_get_stride(image);
  p.data = cairo_image_surface_get_data(image);
  p.alpha = format == CAIRO_FORMAT_ARGB32;
  if (!p.data || p.width <= 0 || p.height <= 0 || (format != CAIRO_FORMAT_ARGB32 && format != CAIRO_FORMAT_RGB24))
    throw InputError(what + ": cannot encode PNG (not an RGB image surface)");
  return p;
}

std::vector<unsigned char> EncodePng(cairo_surface_t* image, const std::string& what) {
  return EncodePixels(PixelsOf(image, what), what);
}

std::vector<unsigned char> EncodePixels(const Pixels& pixels, const std::string& what) {
  const int w = pixels.width, h = pixels.height, stride = pixels.stride;
  const unsigned char* data = pixels.data;
  const bool alpha = pixels.alpha;
  std::vector<unsigned char> out;
  std::vector<unsigned char> row(size_t(w) * (alpha ? 4 : 3));
  ErrorSink sink;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, Fail, Warn);
  if (!png) throw InputError(what + ": cannot encode PNG (out of memory)");
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw InputError(what + ": cannot encode PNG (" + (info ? sink.message : "out of memory") + ")");
  }
  {
    png_set_write_fn(png, &out, Append, NoFlush);
    png_set_compression_level(png, 1);
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
    png_set_IHDR(png, info, png_uint_32(w), png_uint_32(h), 8, alpha ? PNG_COLOR_TYPE_RGB_ALPHA : PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_BASE, PNG_FILTER_TYPE_BASE);
    png_write_info(png, info);
    for (int y = 0; y < h; ++y) {
      const auto* src = reinterpret_cast<const uint32_t*>(data + size_t(y) * stride);
      unsigned char* d = row.data();
      for (int x = 0; x < w; ++x) {
        const uint32_t p = src[x];
        const uint32_t a = alpha ? p >> 24 : 255u;
        uint32_t r = (p >> 16) & 0xffu, g = (p >> 8) & 0xffu, b = p & 0xffu;
        if (alpha && a != 255u) {  // premultiplied -> straight, rounded as cairo's writer does
          if (a == 0) {
            r = g = b = 0;
          } else {
            r = (r * 255u + a / 2) / a, g = (g * 255u + a / 2) / a, b = (b * 255u + a / 2) / a;
          }
        }
        *d++ = static_cast<unsigned char>(r), *d++ = static_cast<unsigned char>(g), *d++ = static_cast<unsigned char>(b);
        if (alpha) *d++ = static_cast<unsigned char>(a);
      }
      png_write_row(png, row.data());
    }
    png_write_end(png, info);
  }
  png_destroy_write_struct(&png, &info);
  return out;
}

void WriteBytes(const std::vector<unsigned char>& bytes, const std::string& path) {
  AtomicWrite(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    f.close();
    if (!f) throw InputError(path + ": cannot write");
  });
}

void WritePng(cairo_surface_t* image, const std::string& path) { WriteBytes(EncodePng(image, path), path); }

void AttachPng(cairo_surface_t* image, std::vector<unsigned char> png, const std::string& what) {
  auto* bytes = new std::vector<unsigned char>(std::move(png));
  const cairo_status_t st =
      cairo_surface_set_mime_data(image, CAIRO_MIME_TYPE_PNG, bytes->data(), bytes->size(),
                                  [](void* p) { delete static_cast<std::vector<unsigned char>*>(p); }, bytes);
  if (st != CAIRO_STATUS_SUCCESS) {
    delete bytes;
    throw InputError(what + ": cannot embed PNG (" + cairo_status_to_string(st) + ")");
  }
}

}  // namespace furnihost::app
