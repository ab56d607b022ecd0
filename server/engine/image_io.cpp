// JPEG through libjpeg-turbo's TurboJPEG API (SIMD DCT and Huffman coding), PNG through
// stb_image_write, both linked from the system's libraries (conventions in image_io.hpp).
// Either library reports failure only for allocation or size problems; both become errors.
#include "image_io.hpp"

#include <memory>
#include <sstream>

#include <stb/stb_image_write.h>
#include <turbojpeg.h>

#include "errors.hpp"

namespace marzipan {

namespace {

// stb's writers index with int: keep every buffer well inside that.
constexpr int kMaxImageSide = 16384;

void validate(const std::vector<std::uint8_t>& rgb, int width, int height) {
  for (const auto& [v, name] : {std::pair{width, "width"}, std::pair{height, "height"}}) {
    if (v < 1 || v > kMaxImageSide) {
      std::ostringstream s;
      s << "must be between 1 and " << kMaxImageSide << " pixels (got " << v << ")";
      throw EngineError(v > kMaxImageSide ? ErrorKind::TooLarge : ErrorKind::InvalidArgument, name, s.str());
    }
  }
  const std::size_t expected = std::size_t(width) * std::size_t(height) * 3;
  if (rgb.size() != expected) {
    std::ostringstream s;
    s << "must hold width*height*3 = " << expected << " bytes (got " << rgb.size() << ")";
    throw EngineError(ErrorKind::InvalidArgument, "rgb", s.str());
  }
}

void append(void* context, void* data, int size) {
  auto* out = static_cast<std::vector<std::uint8_t>*>(context);
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  out->insert(out->end(), bytes, bytes + size);
}

}  // namespace

std::vector<std::uint8_t> encodeJpeg(const std::vector<std::uint8_t>& rgb, int width, int height, int quality) {
  validate(rgb, width, height);
  if (quality < 1 || quality > 100) {
    std::ostringstream s;
    s << "must be between 1 and 100 (got " << quality << ")";
    throw EngineError(ErrorKind::InvalidArgument, "quality", s.str());
  }
  // A compressor per thread: a handle is not safe to share, and creating one per frame costs
  // more than small frames take to encode.
  struct HandleDeleter {
    void operator()(void* h) const { tjDestroy(h); }
  };
  thread_local std::unique_ptr<void, HandleDeleter> handle(tjInitCompress());
  if (!handle) throw EngineError(ErrorKind::Format, "", "JPEG encoder could not be created");
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  const int subsampling = quality <= 90 ? TJSAMP_420 : TJSAMP_444;
  const int status = tjCompress2(handle.get(), rgb.data(), width, width * 3, height, TJPF_RGB, &buffer, &size,
                                 subsampling, quality, 0);
  std::unique_ptr<unsigned char, void (*)(unsigned char*)> owned(buffer, tjFree);
  if (status != 0) throw EngineError(ErrorKind::Format, "", std::string("JPEG encoding failed: ") + tjGetErrorStr2(handle.get()));
  return std::vector<std::uint8_t>(buffer, buffer + size);
}

std::vector<std::uint8_t> encodePng(const std::vector<std::uint8_t>& rgb, int width, int height) {
  validate(rgb, width, height);
  std::vector<std::uint8_t> out;
  if (!stbi_write_png_to_func(append, &out, width, height, 3, rgb.data(), width * 3))
    throw EngineError(ErrorKind::Format, "", "PNG encoding failed");
  return out;
}

std::vector<std::uint8_t> encodeImage(const std::vector<std::uint8_t>& rgb, int width, int height, ImageFormat format,
                                      int quality) {
  return format == ImageFormat::Jpeg ? encodeJpeg(rgb, width, height, quality) : encodePng(rgb, width, height);
}

}  // namespace marzipan
