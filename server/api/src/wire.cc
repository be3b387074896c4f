#include "npfkct/api/wire.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <vector>

namespace npfkct::api {
namespace {

// Each byte's base64 value (both alphabets, standard and URL-safe), or -1.
constexpr std::array<int8_t, 256> kBase64Values = [] {
  std::array<int8_t, 256> v{};
  v.fill(-1);
  for (int c = 'A'; c <= 'Z'; ++c) v[c] = static_cast<int8_t>(c - 'A');
  for (int c = 'a'; c <= 'z'; ++c) v[c] = static_cast<int8_t>(c - 'a' + 26);
  for (int c = '0'; c <= '9'; ++c) v[c] = static_cast<int8_t>(c - '0' + 52);
  v['+'] = v['-'] = 62;
  v['/'] = v['_'] = 63;
  return v;
}();

int Base64Value(char c) { return kBase64Values[static_cast<unsigned char>(c)]; }

uint32_t BigEndian32(const unsigned char* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}

}  // namespace

std::string Base64Encode(std::string_view bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (static_cast<uint8_t>(bytes[i]) << 16) |
                       (static_cast<uint8_t>(bytes[i + 1]) << 8) |
                       static_cast<uint8_t>(bytes[i + 2]);
    out += kAlphabet[v >> 18];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += kAlphabet[v & 63];
  }
  if (i < bytes.size()) {
    uint32_t v = static_cast<uint8_t>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 1]) << 8;
    out += kAlphabet[v >> 18];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

StatusOr<std::string> Base64Decode(std::string_view text, const std::string& field,
                                   size_t max_bytes) {
  // A bound before decoding that leaves room for line breaks and spaces (MIME wraps lines at
  // 76 characters): the exact count is checked on the bytes decoded.
  if (text.size() / 8 > max_bytes / 3 + 1) {
    return InvalidFieldError(field, "more than " + std::to_string(max_bytes) + " bytes");
  }
  std::string out(text.size() / 4 * 3 + 3, '\0');
  size_t n = 0;
  // Whole blocks of four characters of the alphabet, three bytes each (the bulk of a frame's
  // megabytes); anything else (whitespace, padding, a bad character) ends the fast path and the
  // rest goes a character at a time.
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  size_t i = 0;
  for (; i + 4 <= text.size(); i += 4) {
    const int a = kBase64Values[p[i]], b = kBase64Values[p[i + 1]], c = kBase64Values[p[i + 2]],
              d = kBase64Values[p[i + 3]];
    if ((a | b | c | d) < 0) break;
    const uint32_t block = (uint32_t(a) << 18) | (uint32_t(b) << 12) | (uint32_t(c) << 6) | d;
    out[n++] = static_cast<char>(block >> 16);
    out[n++] = static_cast<char>((block >> 8) & 0xff);
    out[n++] = static_cast<char>(block & 0xff);
  }
  uint32_t buffer = 0;
  int bits = 0;
  size_t padding = 0;
  for (char c : text.substr(i)) {
    if (c == '\n' || c == '\r' || c == ' ') continue;
    if (c == '=') {
      ++padding;
      continue;
    }
    if (padding > 0) return InvalidFieldError(field, "not base64: data after padding");
    const int v = Base64Value(c);
    if (v < 0) return InvalidFieldError(field, "not base64: unexpected character");
    buffer = (buffer << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      if (n == out.size()) out.resize(out.size() + 3);
      out[n++] = static_cast<char>((buffer >> bits) & 0xff);
    }
  }
  out.resize(n);
  if (padding > 2) return InvalidFieldError(field, "not base64: too much padding");
  if (out.size() > max_bytes) {
    return InvalidFieldError(field, "more than " + std::to_string(max_bytes) + " bytes");
  }
  return out;
}

StatusOr<ImageInfo> ProbeImage(std::string_view bytes, const std::string& field) {
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t n = bytes.size();
  ImageInfo info;
  if (n >= 8 && std::memcmp(p, "\x89PNG\r\n\x1a\n", 8) == 0) {
    // The first chunk must be IHDR: length 13, then width and height (big-endian).
    if (n < 24 || std::memcmp(p + 12, "IHDR", 4) != 0) {
      return InvalidFieldError(field, "a PNG without its IHDR header");
    }
    info.format = ImageInfo::Format::kPng;
    info.width = BigEndian32(p + 16);
    info.height = BigEndian32(p + 20);
  } else if (n >= 3 && p[0] == 0xff && p[1] == 0xd8 && p[2] == 0xff) {
    // Walk every marker: the size from the first start-of-frame (SOF0..SOF15 but DHT, JPG and
    // DAC), and the components of every scan counted, since the decoder passes over each
    // component of the scan in the whole image.
    info.format = ImageInfo::Format::kJpeg;
    size_t i = 2;
    bool found = false;
    int component_scans = 0;
    while (i + 4 <= n) {
      if (p[i] != 0xff) {
        if (!found) return InvalidFieldError(field, "a JPEG with a broken marker");
        ++i;  // bytes between segments, which the decoder skips to the next marker as well
        continue;
      }
      const unsigned char marker = p[i + 1];
      if (marker == 0xff || marker == 0x00) {  // fill byte; a stuffed zero is no marker
        ++i;
        continue;
      }
      if (marker == 0xd8 || marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) {
        i += 2;
        continue;
      }
      if (marker == 0xd9) break;  // end of image
      const size_t length = (size_t{p[i + 2]} << 8) | p[i + 3];
      if (length < 2) return InvalidFieldError(field, "a JPEG with a broken segment");
      if (marker >= 0xc9 && marker <= 0xcf) {  // SOF9..SOF15 and DAC (0xcc)
        return InvalidFieldError(field,
                                 "an arithmetic-coded JPEG (rare, and its scans decode five times "
                                 "slower than Huffman-coded ones)");
      }
      if (!found && marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 &&
          marker != 0xcc) {
        if (i + 9 > n) break;
        info.height = (int64_t{p[i + 5]} << 8) | p[i + 6];
        info.width = (int64_t{p[i + 7]} << 8) | p[i + 8];
        found = true;
      }
      const int scan_components = marker == 0xda && i + 4 < n ? p[i + 4] : 0;
      i += 2 + length;
      if (marker != 0xda) continue;
      if (!found) break;  // data before any frame header: refused below
      component_scans += std::max(scan_components, 1);
      if (component_scans > kMaxJpegComponentScans) {
        return InvalidFieldError(
            field, "a JPEG whose scans cover more than " + std::to_string(kMaxJpegComponentScans) +
                       " components in all (a progressive colour one covers 14)");
      }
      // The scan's entropy-coded data runs to the next marker: 0xff followed by neither a
      // stuffed zero nor a restart marker.
      while (i + 1 < n &&
             !(p[i] == 0xff && p[i + 1] != 0x00 && !(p[i + 1] >= 0xd0 && p[i + 1] <= 0xd7))) {
        ++i;
      }
    }
    if (!found) return InvalidFieldError(field, "a JPEG without a frame header before its data");
  } else {
    return InvalidFieldError(field, "not a PNG or JPEG image");
  }
  if (info.width <= 0 || info.height <= 0) {
    return InvalidFieldError(field, "the image header gives no size");
  }
  return info;
}

std::string PngDecodingChunks(std::string_view bytes) {
  // Critical chunks and the ancillary ones that say how to read the pixels; text (tEXt, zTXt,
  // iTXt), profiles, animation and private chunks are dropped.
  static constexpr std::string_view kKept[] = {"IHDR", "PLTE", "IDAT", "IEND", "tRNS",
                                               "gAMA", "cHRM", "sRGB", "sBIT", "bKGD"};
  std::string out(bytes.substr(0, std::min<size_t>(bytes.size(), 8)));
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  size_t i = 8;
  while (i + 12 <= bytes.size()) {
    const size_t length = BigEndian32(p + i);
    const std::string_view type = bytes.substr(i + 4, 4);
    if (length > bytes.size() - i - 12) break;  // cut short: the decoder reports it
    if (std::find(std::begin(kKept), std::end(kKept), type) != std::end(kKept)) {
      out.append(bytes.substr(i, 12 + length));
    }
    i += 12 + length;
    if (type == "IEND") return out;
  }
  out.append(bytes.substr(std::min(i, bytes.size())));
  return out;
}

StatusOr<cv::Mat> DecodeImage(std::string_view bytes, int64_t max_pixels,
                              const std::string& field) {
  auto info = ProbeImage(bytes, field);
  if (!info.ok()) return info.status();
  if (info->width > max_pixels || info->height > max_pixels ||
      info->width * info->height > max_pixels) {
    return InvalidFieldError(field, "the image is " + std::to_string(info->width) + " x " +
                                        std::to_string(info->height) + " pixels, more than " +
                                        std::to_string(max_pixels));
  }
  if (bytes.size() > static_cast<size_t>(INT32_MAX)) {
    return InvalidFieldError(field, "too many bytes");
  }
  // libpng inflates every compressed text chunk (up to 8 MB each, a thousand per image): a few
  // kilobytes of zTXt cost a second of CPU. Decoding reads only the chunks that hold pixels.
  std::string png;
  if (info->format == ImageInfo::Format::kPng) {
    png = PngDecodingChunks(bytes);
    bytes = png;
  }
  cv::Mat image;
  try {
    const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
    // Pixels as stored: an EXIF orientation would turn or mirror them away from the cloud, the
    // intrinsics and the header's size.
    image = cv::imdecode(raw, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const cv::Exception&) {
    image.release();
  }
  if (image.empty()) return InvalidFieldError(field, "not a decodable PNG or JPEG image");
  if (image.cols != info->width || image.rows != info->height) {
    // A header that lied (e.g. a second frame of another size): refuse rather than guess.
    return InvalidFieldError(field, "the decoded image does not have the size of its header");
  }
  return image;
}

StatusOr<std::string> EncodePng(const cv::Mat& image) {
  std::vector<uchar> png;
  try {
    if (!cv::imencode(".png", image, png)) return InternalError("PNG encoding failed");
  } catch (const cv::Exception& e) {
    return InternalError(std::string("PNG encoding failed: ") + e.what());
  }
  return std::string(png.begin(), png.end());
}

StatusOr<perception::Cloud::Ptr> DecodeCloud(std::string_view bytes, const std::string& fields,
                                             int64_t max_points, double max_coordinate,
                                             const std::string& field) {
  if (fields != "xyz" && fields != "xyzrgb") {
    return InvalidFieldError(field + ".fields", "expected \"xyz\" or \"xyzrgb\"");
  }
  const size_t stride = fields == "xyz" ? 12 : 16;
  const std::string data = field + ".data";
  if (bytes.empty()) return InvalidFieldError(data, "the cloud is empty");
  if (bytes.size() % stride != 0) {
    return InvalidFieldError(data, std::to_string(bytes.size()) +
                                       " bytes is not a whole number of " + std::to_string(stride) +
                                       "-byte points");
  }
  const size_t n = bytes.size() / stride;
  if (static_cast<int64_t>(n) > max_points) {
    return InvalidFieldError(
        data, std::to_string(n) + " points, more than " + std::to_string(max_points));
  }
  // Every coordinate is checked before PCL sees the cloud: huge finite values overflow PCL's
  // voxel grids and kd-trees.
  for (size_t i = 0; i < n; ++i) {
    float v[3];
    std::memcpy(v, bytes.data() + i * stride, sizeof v);
    for (float c : v) {
      if (!std::isfinite(c)) {
        return InvalidFieldError(
            data, "point " + std::to_string(i) + " is not finite (drop NaN points before sending)");
      }
      if (std::abs(c) > max_coordinate) {
        return InvalidFieldError(data, "point " + std::to_string(i) + " has a coordinate beyond " +
                                           std::to_string(static_cast<int64_t>(max_coordinate)) +
                                           " m");
      }
    }
  }
  auto cloud = pcl::make_shared<perception::Cloud>();
  cloud->resize(n);
  for (size_t i = 0; i < n; ++i) {
    float v[4] = {0, 0, 0, 0};
    std::memcpy(v, bytes.data() + i * stride, stride);
    auto& p = (*cloud)[i];
    p.x = v[0];
    p.y = v[1];
    p.z = v[2];
    if (stride == 16) {
      uint32_t rgb;
      std::memcpy(&rgb, &v[3], 4);
      p.r = (rgb >> 16) & 0xff;
      p.g = (rgb >> 8) & 0xff;
      p.b = rgb & 0xff;
    } else {
      p.r = p.g = p.b = 128;
    }
  }
  cloud->width = static_cast<uint32_t>(n);
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

std::string EncodeCloud(const perception::Cloud& cloud) {
  std::string bytes(cloud.size() * 16, '\0');
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto& p = cloud[i];
    const uint32_t rgb = (static_cast<uint32_t>(p.r) << 16) | (static_cast<uint32_t>(p.g) << 8) |
                         static_cast<uint32_t>(p.b);
    float v[4] = {p.x, p.y, p.z, 0.0f};
    std::memcpy(&v[3], &rgb, 4);
    std::memcpy(bytes.data() + i * 16, v, 16);
  }
  return bytes;
}

}  // namespace npfkct::api
