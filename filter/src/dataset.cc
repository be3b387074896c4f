#include "npfkct/filter/dataset.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>

namespace npfkct::filter {
namespace {

constexpr char kMagic[8] = {'N', 'P', 'F', 'K', 'D', 'S', '0', '1'};
constexpr int32_t kVersion = 2;

template <class T>
void Put(std::ofstream& f, const T* data, size_t n) {
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(n * sizeof(T)));
}

template <class T>
bool Get(std::ifstream& f, T* data, size_t n) {
  f.read(reinterpret_cast<char*>(data), static_cast<std::streamsize>(n * sizeof(T)));
  return static_cast<size_t>(f.gcount()) == n * sizeof(T);
}

}  // namespace

Status WriteDataset(const Dataset& data, const std::string& path) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) return InvalidArgumentError("cannot write " + path);
  const int32_t header[8] = {kVersion,
                             kPoints,
                             kPointDim,
                             kImageSize,
                             kImageChannels,
                             kQueryDim,
                             data.queries_per_sample,
                             static_cast<int32_t>(data.samples.size())};
  f.write(kMagic, sizeof(kMagic));
  Put(f, header, 8);
  std::vector<uint8_t> image(kImageChannels * kImageSize * kImageSize);
  for (const Sample& s : data.samples) {
    if (s.num_queries() != data.queries_per_sample ||
        s.queries.size() != s.scores.size() * kQueryDim ||
        s.scene.points.size() != static_cast<size_t>(kPoints * kPointDim) ||
        s.scene.image.size() != image.size()) {
      return InvalidArgumentError("dataset: a sample has the wrong shape");
    }
    Put(f, s.scene.points.data(), s.scene.points.size());
    for (size_t i = 0; i < image.size(); ++i) {
      image[i] = static_cast<uint8_t>(std::lround(std::clamp(s.scene.image[i], 0.0f, 1.0f) * 255));
    }
    Put(f, image.data(), image.size());
    Put(f, s.queries.data(), s.queries.size());
    Put(f, s.scores.data(), s.scores.size());
  }
  f.flush();
  if (!f) return InternalError("write failed: " + path);
  return OkStatus();
}

StatusOr<Dataset> ReadDataset(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return InvalidArgumentError("cannot open " + path);
  char magic[8];
  int32_t header[8];
  if (!Get(f, magic, 8) || std::memcmp(magic, kMagic, 8) != 0) {
    return InvalidArgumentError(path + ": not an npfkct filter dataset (bad magic)");
  }
  if (!Get(f, header, 8)) return InvalidArgumentError(path + ": truncated header");
  const int32_t expect[6] = {kVersion, kPoints, kPointDim, kImageSize, kImageChannels, kQueryDim};
  if (std::memcmp(header, expect, sizeof(expect)) != 0) {
    return InvalidArgumentError(path + ": dataset version or feature sizes differ from this build");
  }
  const int m = header[6], n = header[7];
  if (m < 1 || n < 0) return InvalidArgumentError(path + ": bad sample counts");
  Dataset data;
  data.queries_per_sample = m;
  data.samples.resize(n);
  std::vector<uint8_t> image(kImageChannels * kImageSize * kImageSize);
  for (int i = 0; i < n; ++i) {
    Sample& s = data.samples[i];
    s.scene.points.resize(kPoints * kPointDim);
    s.scene.image.resize(image.size());
    s.queries.resize(static_cast<size_t>(m) * kQueryDim);
    s.scores.resize(m);
    if (!Get(f, s.scene.points.data(), s.scene.points.size()) ||
        !Get(f, image.data(), image.size()) || !Get(f, s.queries.data(), s.queries.size()) ||
        !Get(f, s.scores.data(), s.scores.size())) {
      return InvalidArgumentError(path + ": truncated at sample " + std::to_string(i));
    }
    for (size_t k = 0; k < image.size(); ++k) s.scene.image[k] = image[k] / 255.0f;
  }
  return data;
}

}  // namespace npfkct::filter
