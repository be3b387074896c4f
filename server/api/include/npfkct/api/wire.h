// Wire formats of the API: Base64 (RFC 4648), PNG/JPEG images (sized from their headers before
// any pixel is decoded) and float32 point buffers. Every decoder takes its limit and the field
// it reads, so that errors name the field and nothing beyond the limit is allocated.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>

#include "npfkct/common/status.h"
#include "npfkct/perception/perception.h"

namespace npfkct::api {

/// Base64 encoding (standard alphabet, padded).
std::string Base64Encode(std::string_view bytes);
/// Base64 decoding (standard or URL-safe alphabet, padding optional, whitespace ignored);
/// INVALID_ARGUMENT naming `field` on anything else. `max_bytes` bounds the decoded size, checked
/// before decoding.
StatusOr<std::string> Base64Decode(std::string_view text, const std::string& field,
                                   size_t max_bytes = SIZE_MAX);

/// What an image's header says.
struct ImageInfo {
  enum class Format { kPng, kJpeg };
  Format format = Format::kPng;
  int64_t width = 0;
  int64_t height = 0;
};
/// Components a JPEG's scans may cover in all (a scan counts each component it codes): the
/// decoder passes over each of them in the whole image, and a scan can take a few bytes. A
/// progressive colour JPEG has 10 scans covering 14; a sequential one 1 or 3.
inline constexpr int kMaxJpegComponentScans = 40;
/// Reads the format and size of PNG or JPEG bytes from the header alone (PNG IHDR, JPEG SOFn);
/// INVALID_ARGUMENT naming `field` when they are neither, the header is cut short, or a JPEG is
/// arithmetic-coded or its scans cover more than kMaxJpegComponentScans components.
StatusOr<ImageInfo> ProbeImage(std::string_view bytes, const std::string& field);
/// The PNG with only the chunks that decoding its pixels needs (critical chunks, tRNS, gAMA,
/// cHRM, sRGB, sBIT, bKGD), in their order; bytes after a cut-short chunk are kept as they are.
std::string PngDecodingChunks(std::string_view bytes);
/// Decodes PNG or JPEG bytes to 8-bit BGR after checking from the header that the image has at
/// most `max_pixels` pixels (INVALID_ARGUMENT naming `field` otherwise); a PNG's other chunks
/// are not read (PngDecodingChunks).
StatusOr<cv::Mat> DecodeImage(std::string_view bytes, int64_t max_pixels, const std::string& field);
/// Encodes an 8-bit image as PNG.
StatusOr<std::string> EncodePng(const cv::Mat& image);

/// Decodes a float32 point buffer ("xyz": 3 little-endian floats per point; "xyzrgb": 4, the
/// fourth packing 0x00RRGGBB as in PCL). More than `max_points` points, a coordinate that is not
/// finite or beyond `max_coordinate` (m) are INVALID_ARGUMENT naming `field`.data, checked before
/// any point is stored.
StatusOr<perception::Cloud::Ptr> DecodeCloud(std::string_view bytes, const std::string& fields,
                                             int64_t max_points, double max_coordinate,
                                             const std::string& field);
/// Encodes a cloud as "xyzrgb" float32 bytes (not Base64).
std::string EncodeCloud(const perception::Cloud& cloud);

}  // namespace npfkct::api
