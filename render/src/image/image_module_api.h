// image_module_api.h: the C interface between the renderer (image_io.cpp) and the loadable image
// module (image_oiio.cpp, built as plantview_image_oiio), which does all image file work through
// OpenImageIO.
//
// Why a module: OpenImageIO pulls in some 260 shared libraries whose loading costs about half a
// second. Linked into the program, every run paid it before main(); loaded with dlopen, only runs
// that touch images pay it, and preload_image_io() (render.h) moves it off the critical path.
//
// Rules of the interface:
//   - The module exports one symbol, plantview_image_api_v2, returning a pointer to a static
//     table valid for the life of the process (the module is never unloaded). A change to any
//     signature or meaning below is a new version: a new struct and a new symbol name.
//   - Only C types cross: pointers, sizes, numbers. No C++ exception leaves the module.
//   - Pixels are RGBA8, rows top first, width * height * 4 bytes, 1..16384 per side; the caller
//     checks sizes before calling. Alpha is dropped when writing.
//   - Every function returns 1 on success, 0 on failure with a NUL-terminated message in
//     `error` (truncated to error_size bytes) that names the file where there is one.
//   - Output of unknown size comes through `allocate(context, bytes)`, called at most once per
//     call: it returns a writable buffer of `bytes` bytes owned by the caller, or null (the call
//     then fails). It must not throw.
//   - Any thread may call; calls on different images do not share state.
#pragma once

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define PLANTVIEW_IMAGE_API_VERSION 2u  /* 2: caption */
#define PLANTVIEW_IMAGE_API_SYMBOL "plantview_image_api_v2"

enum PlantviewImageFormat { PLANTVIEW_IMAGE_PNG = 0, PLANTVIEW_IMAGE_JPEG = 1 };

typedef uint8_t* (*PlantviewImageAllocate)(void* context, size_t bytes);

// What compare finds over the RGB channels, each 0..1 per channel.
struct PlantviewImageDifference {
  double max_error;          // largest channel difference
  double rms_error;          // root mean square of the channel differences
  uint64_t failing_pixels;   // pixels with any channel differing by more than `threshold`
};

struct PlantviewImageApiV2 {
  uint32_t version;      // PLANTVIEW_IMAGE_API_VERSION
  uint32_t struct_size;  // sizeof(struct PlantviewImageApiV2), a check on the build

  // Encodes `rgba` as PNG or JPEG (quality 1..100; ignored for PNG) into one buffer from
  // `allocate`.
  int (*encode)(const uint8_t* rgba, uint32_t width, uint32_t height, int format,
                int jpeg_quality, PlantviewImageAllocate allocate, void* context, char* error,
                size_t error_size);
  // Writes `rgba` to the file `path` (NUL-terminated) as PNG or JPEG.
  int (*write)(const char* path, const uint8_t* rgba, uint32_t width, uint32_t height,
               int format, int jpeg_quality, char* error, size_t error_size);
  // Reads any image file OpenImageIO knows as RGBA8 into one buffer of width * height * 4
  // bytes from `allocate`: grey replicated to RGB, alpha 255 where the file has none. Fails
  // for images over max_side in either direction.
  int (*read)(const char* path, uint32_t max_side, uint32_t* width, uint32_t* height,
              PlantviewImageAllocate allocate, void* context, char* error, size_t error_size);
  // Compares the RGB channels of two images of the same size.
  int (*compare)(const uint8_t* a, const uint8_t* b, uint32_t width, uint32_t height,
                 double threshold, struct PlantviewImageDifference* out, char* error,
                 size_t error_size);
  // Draws a caption strip along the bottom of `rgba` in place (image.h add_caption): `title`
  // in DejaVu Sans Bold, then `line_count` lines (each NUL-terminated UTF-8) in DejaVu Sans,
  // dark on a light strip. Fails when a font file cannot be found.
  int (*caption)(uint8_t* rgba, uint32_t width, uint32_t height, const char* title,
                 const char* const* lines, size_t line_count, char* error, size_t error_size);
};

typedef const struct PlantviewImageApiV2* (*PlantviewImageApiV2Entry)(void);

#ifdef __cplusplus
}
#endif
