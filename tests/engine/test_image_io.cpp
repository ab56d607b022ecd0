// JPEG and PNG encoding, checked by decoding the result with stb_image (from the same libstb).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <vector>

#include <stb/stb_image.h>

#include "engine/errors.hpp"
#include "engine/image_io.hpp"

using namespace marzipan;

namespace {

struct Decoded {
  int width = 0, height = 0, channels = 0;
  std::vector<std::uint8_t> rgb;
};

Decoded decode(const std::vector<std::uint8_t>& file) {
  Decoded d;
  std::unique_ptr<stbi_uc, void (*)(void*)> px(
      stbi_load_from_memory(file.data(), int(file.size()), &d.width, &d.height, &d.channels, 3), stbi_image_free);
  REQUIRE(px);
  d.rgb.assign(px.get(), px.get() + std::size_t(d.width) * d.height * 3);
  return d;
}

// Smooth ramps, so that JPEG's error stays small and measurable.
std::vector<std::uint8_t> ramps(int w, int h) {
  std::vector<std::uint8_t> rgb(std::size_t(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = &rgb[(std::size_t(y) * w + x) * 3];
      p[0] = std::uint8_t(255 * x / (w - 1));
      p[1] = std::uint8_t(255 * y / (h - 1));
      p[2] = std::uint8_t(128 + 100 * std::sin(0.05 * (x + y)));
    }
  return rgb;
}

}  // namespace

TEST_CASE("PNG round-trips losslessly", "[image]") {
  const int w = 37, h = 23;  // odd sizes: no row padding may creep in
  std::vector<std::uint8_t> rgb(std::size_t(w) * h * 3);
  std::uint32_t state = 12345;
  for (auto& b : rgb) {
    state = state * 1664525u + 1013904223u;
    b = std::uint8_t(state >> 24);
  }
  const auto png = encodePng(rgb, w, h);
  REQUIRE(png.size() > 8);
  CHECK(png[0] == 0x89);
  CHECK(png[1] == 'P');
  const Decoded d = decode(png);
  CHECK(d.width == w);
  CHECK(d.height == h);
  CHECK(d.channels == 3);
  CHECK(d.rgb == rgb);
  CHECK(encodeImage(rgb, w, h, ImageFormat::Png) == png);
}

TEST_CASE("JPEG decodes to the right size and close pixels", "[image]") {
  const int w = 64, h = 48;
  const auto rgb = ramps(w, h);
  const auto jpg = encodeJpeg(rgb, w, h, 95);
  REQUIRE(jpg.size() > 4);
  CHECK(jpg[0] == 0xFF);
  CHECK(jpg[1] == 0xD8);
  const Decoded d = decode(jpg);
  CHECK(d.width == w);
  CHECK(d.height == h);
  double sum = 0;
  for (std::size_t i = 0; i < rgb.size(); ++i) sum += std::abs(int(d.rgb[i]) - int(rgb[i]));
  CHECK(sum / double(rgb.size()) < 3.0);
  // Lower quality, smaller file.
  CHECK(encodeJpeg(rgb, w, h, 10).size() < jpg.size());
  CHECK(encodeImage(rgb, w, h, ImageFormat::Jpeg, 95) == jpg);
  // A single pixel is a valid image too.
  const Decoded one = decode(encodeJpeg({200, 100, 50}, 1, 1, 75));
  CHECK(one.width == 1);
  CHECK(one.height == 1);
}

TEST_CASE("invalid images and qualities are refused", "[image][errors]") {
  const auto rgb = ramps(8, 8);
  CHECK_THROWS_AS(encodeJpeg(rgb, 8, 8, 0), EngineError);
  CHECK_THROWS_AS(encodeJpeg(rgb, 8, 8, 101), EngineError);
  CHECK_THROWS_AS(encodePng(rgb, 8, 7), EngineError);
  CHECK_THROWS_AS(encodePng(rgb, 0, 8), EngineError);
  CHECK_THROWS_AS(encodeJpeg({}, 0, 0, 75), EngineError);
  try {
    encodePng(rgb, 100000, 8);
    FAIL("no error");
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::TooLarge);
    CHECK(e.field() == "width");
  }
}
