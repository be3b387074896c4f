// Wire formats: Base64, image headers read before decoding, point buffers with their limits.
#include "npfkct/api/wire.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <opencv2/imgcodecs.hpp>

namespace npfkct::api {
namespace {

std::string Png(int w, int h) {
  std::vector<uchar> out;
  cv::imencode(".png", cv::Mat(h, w, CV_8UC3, cv::Scalar(10, 20, 30)), out);
  return std::string(out.begin(), out.end());
}

std::string Jpeg(int w, int h) {
  std::vector<uchar> out;
  cv::imencode(".jpg", cv::Mat(h, w, CV_8UC3, cv::Scalar(10, 20, 30)), out);
  return std::string(out.begin(), out.end());
}

TEST(Base64, RoundTripsAndNamesTheFieldOnBadInput) {
  for (const std::string& s : std::vector<std::string>{"", "a", "ab", "abc", "hello world",
                                                       std::string("\0\xff\x10", 3)}) {
    EXPECT_EQ(Base64Decode(Base64Encode(s), "f").value(), s);
  }
  auto bad = Base64Decode("!!!", "image.data");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field_violations().at(0).field, "image.data");
  EXPECT_FALSE(Base64Decode("QQ==QQ", "f").ok());                    // data after padding
  EXPECT_FALSE(Base64Decode(std::string(400, 'A'), "f", 100).ok());  // over the size limit
}

// Whole blocks go four characters at a time; whitespace, padding or a bad character anywhere
// hands the rest to the character-at-a-time path, with the same result.
TEST(Base64, BlocksAndTheRestDecodeAlike) {
  std::string bytes;
  for (int i = 0; i < 3000; ++i) bytes += static_cast<char>((i * 7919) & 0xff);
  for (size_t length : {size_t{0}, size_t{1}, size_t{2}, size_t{3}, size_t{1000}, size_t{2999}}) {
    const std::string s = bytes.substr(0, length);
    const std::string text = Base64Encode(s);
    EXPECT_EQ(Base64Decode(text, "f").value(), s) << length;
    std::string wrapped;  // MIME-style lines of 76 characters
    for (size_t k = 0; k < text.size(); k += 76) wrapped += text.substr(k, 76) + "\r\n";
    EXPECT_EQ(Base64Decode(wrapped, "f").value(), s) << length;
    std::string url_safe = text;  // the URL-safe alphabet
    std::replace(url_safe.begin(), url_safe.end(), '+', '-');
    std::replace(url_safe.begin(), url_safe.end(), '/', '_');
    EXPECT_EQ(Base64Decode(url_safe, "f").value(), s) << length;
  }
  const std::string text = Base64Encode(bytes);
  for (size_t at : {size_t{0}, size_t{5}, size_t{2000}, text.size() - 1}) {
    std::string bad = text;
    bad[at] = '*';
    EXPECT_FALSE(Base64Decode(bad, "f").ok()) << at;
  }
}

TEST(ProbeImage, ReadsTheSizeFromTheHeaderAlone) {
  auto png = ProbeImage(Png(40, 30), "p");
  ASSERT_TRUE(png.ok());
  EXPECT_EQ(png->width, 40);
  EXPECT_EQ(png->height, 30);
  auto jpeg = ProbeImage(Jpeg(64, 48), "p");
  ASSERT_TRUE(jpeg.ok()) << jpeg.status().ToString();
  EXPECT_EQ(jpeg->format, ImageInfo::Format::kJpeg);
  EXPECT_EQ(jpeg->width, 64);
  EXPECT_EQ(jpeg->height, 48);
  EXPECT_FALSE(ProbeImage("GIF89a nonsense", "p").ok());
  EXPECT_FALSE(ProbeImage(Png(40, 30).substr(0, 20), "p").ok());
  EXPECT_FALSE(ProbeImage(Jpeg(64, 48).substr(0, 6), "p").ok());
}

TEST(DecodeImage, RefusesAPixelBombBeforeDecoding) {
  // A valid PNG whose header claims 60000 x 60000 pixels (10.8 GB decoded): refused from the
  // header, so nothing is allocated.
  std::string bomb = Png(16, 16);
  const unsigned char size[8] = {0, 0, 0xea, 0x60, 0, 0, 0xea, 0x60};
  std::memcpy(bomb.data() + 16, size, 8);
  auto r = DecodeImage(bomb, 4'194'304, "target.photos[0]");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().field_violations().at(0).field, "target.photos[0]");
  EXPECT_NE(r.status().message().find("60000 x 60000"), std::string::npos);
  // Within the limit it decodes.
  auto ok = DecodeImage(Png(20, 10), 4'194'304, "image.data");
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok->cols, 20);
  EXPECT_EQ(ok->rows, 10);
  EXPECT_EQ(ok->type(), CV_8UC3);
  // A JPEG over the pixel limit.
  EXPECT_FALSE(DecodeImage(Jpeg(300, 300), 80'000, "image.data").ok());
  // Garbage after a PNG signature and IHDR does not decode, and is an error, not a crash.
  std::string broken = Png(16, 16).substr(0, 40) + std::string(100, 'x');
  EXPECT_FALSE(DecodeImage(broken, 4'194'304, "image.data").ok());
}

TEST(DecodeImage, KeepsThePixelsAsStoredWhateverTheExifOrientation) {
  // A 64 x 48 JPEG with an EXIF APP1 segment (Orientation 6, "rotate 90"): OpenCV turned it to
  // 48 x 64, which the header check refused as a lie; orientations that keep the size (2, 3)
  // mirrored or turned the pixels away from the cloud and the intrinsics.
  cv::Mat gradient(48, 64, CV_8UC3);
  for (int r = 0; r < 48; ++r) {
    for (int c = 0; c < 64; ++c) gradient.at<cv::Vec3b>(r, c) = cv::Vec3b(4 * c, 5 * r, 100);
  }
  std::vector<uchar> out;
  cv::imencode(".jpg", gradient, out);
  const std::string plain(out.begin(), out.end());
  for (const char orientation : {'\x06', '\x03', '\x02'}) {
    const std::string tiff = std::string("II*\0\x08\0\0\0", 8) +
                             std::string("\x01\0\x12\x01\x03\0\x01\0\0\0", 10) + orientation +
                             std::string("\0\0\0\0\0\0\0", 7);
    const std::string payload = std::string("Exif\0\0", 6) + tiff;
    const size_t length = payload.size() + 2;
    const std::string app1 = std::string("\xff\xe1", 2) + static_cast<char>(length >> 8) +
                             static_cast<char>(length & 0xff) + payload;
    const std::string exif = plain.substr(0, 2) + app1 + plain.substr(2);
    auto with = DecodeImage(exif, 4'194'304, "image.data");
    ASSERT_TRUE(with.ok()) << int{orientation} << " " << with.status().ToString();
    auto without = DecodeImage(plain, 4'194'304, "image.data");
    ASSERT_TRUE(without.ok());
    ASSERT_EQ(with->size(), without->size());
    EXPECT_EQ(cv::norm(*with, *without, cv::NORM_INF), 0.0) << int{orientation};
  }
}

// The JPEG's segments up to its end-of-image marker, each scan with its entropy-coded data.
std::vector<std::string> JpegSegments(const std::string& jpeg) {
  std::vector<std::string> out;
  const auto at = [&](size_t k) { return static_cast<unsigned char>(jpeg[k]); };
  size_t i = 2;
  while (i + 4 <= jpeg.size() && at(i + 1) != 0xd9) {
    size_t end = i + 2 + ((size_t{at(i + 2)} << 8) | at(i + 3));
    if (at(i + 1) == 0xda) {
      while (end + 1 < jpeg.size() &&
             !(at(end) == 0xff && at(end + 1) != 0 && (at(end + 1) < 0xd0 || at(end + 1) > 0xd7))) {
        ++end;
      }
    }
    out.push_back(jpeg.substr(i, end - i));
    i = end;
  }
  return out;
}

TEST(ProbeImage, RefusesJpegsThatMakeTheDecoderPassOverTheImageTooOften) {
  // A progressive colour JPEG has 10 scans covering 14 components; repeating one of its
  // refinement scans makes the decoder pass over the whole image again each time (2048 x 2048:
  // 3 ms per 16-byte scan), so a few kilobytes cost seconds. A scan of 4 components counts 4.
  cv::Mat gradient(96, 128, CV_8UC3);
  for (int r = 0; r < gradient.rows; ++r) {
    for (int c = 0; c < gradient.cols; ++c) gradient.at<cv::Vec3b>(r, c) = cv::Vec3b(r, c, r + c);
  }
  std::vector<uchar> encoded;
  ASSERT_TRUE(cv::imencode(".jpg", gradient, encoded, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  const std::string progressive(encoded.begin(), encoded.end());
  std::vector<std::string> scans;
  std::string head;
  int components = 0;
  for (const std::string& s : JpegSegments(progressive)) {
    if (static_cast<unsigned char>(s[1]) == 0xda) {
      scans.push_back(s);
      components += s[4];
    } else {
      head += s;
    }
  }
  ASSERT_EQ(scans.size(), 10u);
  ASSERT_EQ(components, 14);
  ASSERT_EQ(scans.back()[4], 1);  // the last refinement scan codes one component
  ASSERT_TRUE(DecodeImage(progressive, 4'194'304, "image.data").ok());
  auto with_extra = [&](int extra) {
    std::string out = "\xff\xd8" + head;
    for (const std::string& scan : scans) out += scan;
    for (int k = 0; k < extra; ++k) out += scans.back();
    return out + "\xff\xd9";
  };
  EXPECT_TRUE(ProbeImage(with_extra(kMaxJpegComponentScans - 14), "image.data").ok());
  auto r = DecodeImage(with_extra(kMaxJpegComponentScans - 13), 4'194'304, "target.photos[2]");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field_violations().at(0).field, "target.photos[2]");
  EXPECT_NE(r.status().message().find("cover more than 40 components"), std::string::npos);
  // Arithmetic coding (SOF9..SOF15, DAC) is refused: its scans decode five times slower, and a
  // 725-byte CMYK JPEG of 32 four-component scans took 0.8 s.
  std::string arithmetic = progressive;
  const size_t sof = arithmetic.find("\xff\xc2");
  ASSERT_NE(sof, std::string::npos);
  arithmetic[sof + 1] = static_cast<char>(0xca);
  auto a = ProbeImage(arithmetic, "image.data");
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("arithmetic-coded"), std::string::npos);
  // Stuffed zeros and restart markers inside a scan are not markers; bytes between segments
  // are skipped as the decoder skips them.
  std::vector<uchar> restarts;
  ASSERT_TRUE(cv::imencode(".jpg", gradient, restarts, {cv::IMWRITE_JPEG_RST_INTERVAL, 1}));
  std::string baseline(restarts.begin(), restarts.end());
  EXPECT_TRUE(ProbeImage(baseline, "p").ok());
  baseline.insert(baseline.find("\xff\xda"), "xyz");  // before the scan, after the frame
  EXPECT_TRUE(ProbeImage(baseline, "p").ok());
  EXPECT_TRUE(DecodeImage(baseline, 4'194'304, "p").ok());
}

TEST(DecodeImage, ReadsOnlyThePngChunksThatHoldPixels) {
  // libpng inflates each zTXt chunk (up to 8 MB each): decoding reads none of them.
  const std::string png = Png(16, 16);
  auto chunk = [](const std::string& type, const std::string& data) {
    std::string out(4, '\0');
    for (int k = 0; k < 4; ++k) out[k] = static_cast<char>((data.size() >> (24 - 8 * k)) & 0xff);
    return out + type + data + std::string(4, '\0');  // the CRC is not read here
  };
  const size_t after_ihdr = 8 + 12 + 13;
  const std::string text = chunk("zTXt", std::string("k\0\0", 3) + std::string(64, 'x')) +
                           chunk("tEXt", "key\0value") + chunk("prIv", std::string(1000, 'p'));
  const std::string noisy = png.substr(0, after_ihdr) + text + png.substr(after_ihdr);
  EXPECT_EQ(PngDecodingChunks(noisy), png);
  EXPECT_EQ(PngDecodingChunks(png), png);
  auto decoded = DecodeImage(noisy, 4'194'304, "image.data");
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->cols, 16);
  // A chunk cut short keeps the bytes after it, and the decoder refuses them.
  const std::string cut =
      png.substr(0, after_ihdr) + chunk("IDAT", std::string(50, 'd')).substr(0, 30);
  EXPECT_EQ(PngDecodingChunks(cut), cut);
  EXPECT_FALSE(DecodeImage(cut, 4'194'304, "image.data").ok());
}

TEST(DecodeCloud, BoundsPointsAndCoordinatesBeforePclSeesThem) {
  perception::Cloud c;
  for (int i = 0; i < 5; ++i) {
    pcl::PointXYZRGB p;
    p.x = 0.1f * i;
    p.y = -0.2f;
    p.z = 1.0f + i;
    p.r = 200;
    p.g = 10;
    p.b = 30;
    c.push_back(p);
  }
  auto back = DecodeCloud(EncodeCloud(c), "xyzrgb", 100, 1e4, "pointCloud");
  ASSERT_TRUE(back.ok());
  ASSERT_EQ((*back)->size(), 5u);
  EXPECT_FLOAT_EQ((**back)[3].z, 4.0f);
  EXPECT_EQ((**back)[3].r, 200);
  // Too many points.
  auto many = DecodeCloud(EncodeCloud(c), "xyzrgb", 4, 1e4, "pointCloud");
  ASSERT_FALSE(many.ok());
  EXPECT_EQ(many.status().field_violations().at(0).field, "pointCloud.data");
  // Finite but huge coordinates (3e38: PCL's voxel grid overflows on them).
  perception::Cloud huge = c;
  huge[2].z = 3e38f;
  auto far = DecodeCloud(EncodeCloud(huge), "xyzrgb", 100, 1e4, "pointCloud");
  ASSERT_FALSE(far.ok());
  EXPECT_NE(far.status().message().find("point 2"), std::string::npos);
  huge[2].z = std::nanf("");
  EXPECT_FALSE(DecodeCloud(EncodeCloud(huge), "xyzrgb", 100, 1e4, "pointCloud").ok());
  EXPECT_FALSE(DecodeCloud(std::string(13, 'x'), "xyz", 100, 1e4, "pointCloud").ok());
  EXPECT_FALSE(DecodeCloud("", "xyz", 100, 1e4, "pointCloud").ok());
  auto fields = DecodeCloud(std::string(12, '\0'), "xyzw", 100, 1e4, "pointCloud");
  ASSERT_FALSE(fields.ok());
  EXPECT_EQ(fields.status().field_violations().at(0).field, "pointCloud.fields");
}

}  // namespace
}  // namespace npfkct::api
