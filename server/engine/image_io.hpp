// Encoding RGB8 images (ray-cast frames, snapshots) to in-memory JPEG or PNG files.
// Conventions: pixels are width*height*3 bytes (R, G, B), rows from the top, no padding.
// Invalid sizes or qualities throw EngineError; the encoders are safe to call from several
// threads at once.
#pragma once

#include <cstdint>
#include <vector>

namespace marzipan {

enum class ImageFormat { Jpeg, Png };

// Baseline JPEG (libjpeg-turbo), 4:2:0 chroma subsampling at quality 90 and below; quality in [1, 100].
std::vector<std::uint8_t> encodeJpeg(const std::vector<std::uint8_t>& rgb, int width, int height, int quality);
// Lossless PNG, 8 bits per channel.
std::vector<std::uint8_t> encodePng(const std::vector<std::uint8_t>& rgb, int width, int height);
// quality is used by JPEG only.
std::vector<std::uint8_t> encodeImage(const std::vector<std::uint8_t>& rgb, int width, int height, ImageFormat format,
                                      int quality = 85);

}  // namespace marzipan
