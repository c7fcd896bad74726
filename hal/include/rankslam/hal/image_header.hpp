#pragma once

#include <optional>
#include <span>

namespace rankslam::hal {

/// What an image file's header declares, read without decoding a pixel.
struct ImageHeader {
  int width = 0;
  int height = 0;
  int channels = 0;   ///< Samples per pixel as stored (a PNG palette counts as 3, colour).
  int bit_depth = 0;  ///< Bits per sample as stored (8 or 16 for the usual files).
};

/// The header of a PNG (IHDR), JPEG (first SOF segment), binary PGM/PPM (P5/P6) or TIFF (first
/// IFD) image in `bytes`; nullopt when the bytes are none of these or the header is cut short
/// or invalid. Lets a reader refuse an image whose size or layout is wrong before the decoder
/// allocates for it: a few kilobytes of PNG can declare gigabytes of pixels.
[[nodiscard]] std::optional<ImageHeader> read_image_header(std::span<const unsigned char> bytes);

}  // namespace rankslam::hal
