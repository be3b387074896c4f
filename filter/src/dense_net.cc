#include "dense_net.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

#include "net_shape.h"

namespace npfkct::filter {
namespace {

constexpr char kMagic[8] = {'N', 'P', 'F', 'K', 'C', 'T', 'W', '1'};
constexpr int kMaxMembersInFile = 8;
constexpr size_t kMaxFileBytes = 64u << 20;
constexpr uint32_t kMaxTensors = 256;
constexpr size_t kMaxName = 128;
constexpr int kMaxRank = 4;
constexpr int64_t kMaxValues = int64_t{1} << 22;

using Matrix = DenseNet::Matrix;
using Vector = DenseNet::Vector;

// Every tensor of the network with its shape: the names of NpNet's parameters and its format
// marker (network.cc registers them so).
std::map<std::string, std::vector<int64_t>> ExpectedShapes() {
  std::map<std::string, std::vector<int64_t>> s;
  auto linear = [&](const std::string& name, int64_t in, int64_t out) {
    s[name + ".weight"] = {out, in};
    s[name + ".bias"] = {out};
  };
  auto mlp = [&](const std::string& name, const std::vector<int64_t>& sizes) {
    for (size_t i = 0; i + 1 < sizes.size(); ++i) {
      linear(name + "." + std::to_string(2 * i), sizes[i], sizes[i + 1]);
    }
  };
  auto attention = [&](const std::string& name) {
    for (const char* w : {"wq", "wk", "wv", "wo"}) linear(name + "." + w, kHidden, kHidden);
    s[name + ".norm.weight"] = {kHidden};
    s[name + ".norm.bias"] = {kHidden};
  };
  mlp("point_mlp", {kPointDim, 32, kHidden});
  s["cnn.0.weight"] = {16, kImageChannels, 5, 5};
  s["cnn.0.bias"] = {16};
  s["cnn.2.weight"] = {32, 16, 3, 3};
  s["cnn.2.bias"] = {32};
  s["cnn.4.weight"] = {32, 32, 3, 3};
  s["cnn.4.bias"] = {32};
  linear("image_fc", 32 * (kImageSize / 8) * (kImageSize / 8), kHidden);
  mlp("scene_mlp", {2 * kHidden, kHidden});
  mlp("query_mlp", {kQueryDim, kHidden, kHidden});
  mlp("latent_mlp", {2 * kHidden + 1, kHidden, kHidden});
  mlp("det_mlp", {2 * kHidden + 1, kHidden, kHidden});
  attention("latent_self");
  attention("det_self");
  attention("cross");
  linear("latent_out", kHidden, 2 * kLatent);
  mlp("decoder", {3 * kHidden + kLatent, kHidden, kHidden, 2});
  s["npfkct_filter_format"] = {8};
  return s;
}

std::vector<float> FormatValues() {
  return {kFormatVersion, kPoints,   kPointDim, kImageSize,
          kImageChannels, kQueryDim, kHidden,   kLatent};
}

void Relu(Matrix* x) { *x = x->cwiseMax(0.0f); }

Matrix ApplyMlp(const std::vector<DenseNet::Linear>& layers, Matrix x, bool relu_last) {
  for (size_t i = 0; i < layers.size(); ++i) {
    x = layers[i].Apply(x);
    if (i + 1 < layers.size() || relu_last) Relu(&x);
  }
  return x;
}

// A convolution of a (channels x size x size) image, row-major, with ReLU: (out x size'^2).
Matrix ConvRelu(const DenseNet::Conv& c, const float* image, int size, int* out_size) {
  const int o = (size + 2 * c.padding - c.kernel) / c.stride + 1;
  *out_size = o;
  Matrix columns(c.in * c.kernel * c.kernel, o * o);
  for (int ch = 0; ch < c.in; ++ch) {
    for (int ky = 0; ky < c.kernel; ++ky) {
      for (int kx = 0; kx < c.kernel; ++kx) {
        const int row = (ch * c.kernel + ky) * c.kernel + kx;
        for (int y = 0; y < o; ++y) {
          const int iy = y * c.stride - c.padding + ky;
          for (int x = 0; x < o; ++x) {
            const int ix = x * c.stride - c.padding + kx;
            columns(row, y * o + x) = iy >= 0 && iy < size && ix >= 0 && ix < size
                                          ? image[(ch * size + iy) * size + ix]
                                          : 0.0f;
          }
        }
      }
    }
  }
  Matrix out = c.weight * columns;
  out.colwise() += c.bias.transpose();
  Relu(&out);
  return out;
}

// [a, b, ...] side by side, each of `rows` rows (a one-row block is repeated on every row).
Matrix Concat(const std::vector<const Matrix*>& blocks, int rows) {
  int cols = 0;
  for (const Matrix* b : blocks) cols += static_cast<int>(b->cols());
  Matrix out(rows, cols);
  int at = 0;
  for (const Matrix* b : blocks) {
    if (b->rows() == rows) {
      out.middleCols(at, b->cols()) = *b;
    } else {
      out.middleCols(at, b->cols()) = b->replicate(rows, 1);
    }
    at += static_cast<int>(b->cols());
  }
  return out;
}

float Softplus(float x) { return x > 20.0f ? x : std::log1p(std::exp(x)); }

class Reader {
 public:
  explicit Reader(std::string bytes) : bytes_(std::move(bytes)) {}
  template <typename T>
  bool Read(T* out) {
    if (bytes_.size() - at_ < sizeof(T)) return false;
    std::memcpy(out, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return true;
  }
  bool ReadBytes(size_t n, std::string* out) {
    if (bytes_.size() - at_ < n) return false;
    out->assign(bytes_, at_, n);
    at_ += n;
    return true;
  }
  bool ReadFloats(size_t n, std::vector<float>* out) {
    if ((bytes_.size() - at_) / sizeof(float) < n) return false;
    out->resize(n);
    std::memcpy(out->data(), bytes_.data() + at_, n * sizeof(float));
    at_ += n * sizeof(float);
    return true;
  }
  bool AtEnd() const { return at_ == bytes_.size(); }

 private:
  std::string bytes_;
  size_t at_ = 0;
};

}  // namespace

Matrix DenseNet::Linear::Apply(const Matrix& x) const {
  Matrix out = x * weight.transpose();
  out.rowwise() += bias;
  return out;
}

Matrix DenseNet::Attention::Apply(const Matrix& q, const Matrix& k, const Matrix& v) const {
  const Matrix qp = wq.Apply(q), kp = wk.Apply(k), vp = wv.Apply(v);
  const int dim = static_cast<int>(qp.cols()), d = dim / kHeads;
  const float scale = 1.0f / std::sqrt(static_cast<float>(d));
  Matrix joined(qp.rows(), dim);
  for (int h = 0; h < kHeads; ++h) {
    Matrix w = (qp.middleCols(h * d, d) * kp.middleCols(h * d, d).transpose()) * scale;
    for (Eigen::Index r = 0; r < w.rows(); ++r) {
      const float top = w.row(r).maxCoeff();
      w.row(r) = (w.row(r).array() - top).exp().matrix();
      w.row(r) /= w.row(r).sum();
    }
    joined.middleCols(h * d, d) = w * vp.middleCols(h * d, d);
  }
  Matrix out = wo.Apply(joined);
  if (!residual) return out;
  out += q;
  for (Eigen::Index r = 0; r < out.rows(); ++r) {
    const float mean = out.row(r).mean();
    const float var = (out.row(r).array() - mean).square().mean();
    out.row(r) =
        ((out.row(r).array() - mean) / std::sqrt(var + 1e-5f)).matrix().cwiseProduct(norm_weight) +
        norm_bias;
  }
  return out;
}

StatusOr<DenseNet> DenseNet::FromTensors(const std::vector<NamedTensor>& tensors) {
  const auto expected = ExpectedShapes();
  std::map<std::string, const NamedTensor*> by_name;
  for (const NamedTensor& t : tensors) {
    auto want = expected.find(t.name);
    if (want == expected.end()) return InvalidArgumentError("unknown tensor '" + t.name + "'");
    if (t.shape != want->second) {
      return InvalidArgumentError("tensor '" + t.name + "' has another shape than the network's");
    }
    if (!by_name.emplace(t.name, &t).second) {
      return InvalidArgumentError("tensor '" + t.name + "' given twice");
    }
  }
  for (const auto& [name, shape] : expected) {
    if (by_name.count(name) == 0) return InvalidArgumentError("tensor '" + name + "' is missing");
  }
  if (by_name["npfkct_filter_format"]->values != FormatValues()) {
    return InvalidArgumentError("the weights were saved by an incompatible filter version");
  }
  for (const auto& [name, t] : by_name) {
    for (float v : t->values) {
      if (!std::isfinite(v)) {
        return InvalidArgumentError("tensor '" + name + "' holds a value that is not finite");
      }
    }
  }
  auto matrix = [&](const std::string& name) {
    const NamedTensor& t = *by_name.at(name);
    const int64_t rows = t.shape[0];
    return Matrix(Eigen::Map<const Matrix>(t.values.data(), rows,
                                           static_cast<int64_t>(t.values.size()) / rows));
  };
  auto vector = [&](const std::string& name) {
    const NamedTensor& t = *by_name.at(name);
    return Vector(Eigen::Map<const Vector>(t.values.data(), static_cast<int64_t>(t.values.size())));
  };
  auto linear = [&](const std::string& name) {
    return Linear{matrix(name + ".weight"), vector(name + ".bias")};
  };
  auto mlp = [&](const std::string& name, int layers) {
    std::vector<Linear> out;
    for (int i = 0; i < layers; ++i) out.push_back(linear(name + "." + std::to_string(2 * i)));
    return out;
  };
  auto attention = [&](const std::string& name, bool residual) {
    return Attention{linear(name + ".wq"),
                     linear(name + ".wk"),
                     linear(name + ".wv"),
                     linear(name + ".wo"),
                     vector(name + ".norm.weight"),
                     vector(name + ".norm.bias"),
                     residual};
  };
  DenseNet net;
  net.point_mlp_ = mlp("point_mlp", 2);
  const int strides[] = {2, 2, 2}, paddings[] = {2, 1, 1};
  for (int i = 0; i < 3; ++i) {
    const std::string name = "cnn." + std::to_string(2 * i);
    const NamedTensor& w = *by_name.at(name + ".weight");
    net.cnn_.push_back(Conv{static_cast<int>(w.shape[1]), static_cast<int>(w.shape[0]),
                            static_cast<int>(w.shape[2]), strides[i], paddings[i],
                            matrix(name + ".weight"), vector(name + ".bias")});
  }
  net.image_fc_ = linear("image_fc");
  net.scene_mlp_ = mlp("scene_mlp", 1);
  net.query_mlp_ = mlp("query_mlp", 2);
  net.latent_mlp_ = mlp("latent_mlp", 2);
  net.det_mlp_ = mlp("det_mlp", 2);
  net.latent_self_ = attention("latent_self", true);
  net.det_self_ = attention("det_self", true);
  net.cross_ = attention("cross", false);
  net.latent_out_ = linear("latent_out");
  net.decoder_ = mlp("decoder", 3);
  return net;
}

Vector DenseNet::EncodeScene(const float* points, const float* image) const {
  const Matrix p = ApplyMlp(point_mlp_, Eigen::Map<const Matrix>(points, kPoints, kPointDim), true);
  const Matrix pooled = p.colwise().maxCoeff();
  Matrix features;
  const float* in = image;
  int size = kImageSize;
  for (const Conv& c : cnn_) {
    int out_size = 0;
    features = ConvRelu(c, in, size, &out_size);
    in = features.data();
    size = out_size;
  }
  Matrix flat = Eigen::Map<const Matrix>(features.data(), 1, features.size());
  Matrix i = image_fc_.Apply(flat);
  Relu(&i);
  return ApplyMlp(scene_mlp_, Concat({&pooled, &i}, 1), true);
}

Matrix DenseNet::EncodeQuery(const float* queries, int n) const {
  return ApplyMlp(query_mlp_, Eigen::Map<const Matrix>(queries, n, kQueryDim), false);
}

Vector DenseNet::LatentMean(const Vector& scene, const Matrix& xc, const float* yc) const {
  const int m = static_cast<int>(xc.rows());
  const Matrix y = Eigen::Map<const Matrix>(yc, m, 1);
  const Matrix s0 = scene;
  Matrix s = ApplyMlp(latent_mlp_, Concat({&xc, &y, &s0}, m), false);
  s = latent_self_.Apply(s, s, s);
  Matrix pooled = s.colwise().mean();
  Relu(&pooled);
  const Matrix out = latent_out_.Apply(pooled);
  return out.leftCols(kLatent);
}

Matrix DenseNet::Deterministic(const Vector& scene, const Matrix& xc, const float* yc,
                               const Matrix& xt) const {
  const int m = static_cast<int>(xc.rows());
  const Matrix y = Eigen::Map<const Matrix>(yc, m, 1);
  const Matrix s0 = scene;
  Matrix r = ApplyMlp(det_mlp_, Concat({&xc, &y, &s0}, m), false);
  r = det_self_.Apply(r, r, r);
  return cross_.Apply(xt, xc, r);
}

std::pair<Vector, Vector> DenseNet::Decode(const Vector& scene, const Matrix& xc, const float* yc,
                                           const Matrix& xt, const Vector& z) const {
  const int n = static_cast<int>(xt.rows());
  const Matrix r = Deterministic(scene, xc, yc, xt);
  const Matrix z0 = z, s0 = scene;
  const Matrix out = ApplyMlp(decoder_, Concat({&xt, &r, &z0, &s0}, n), false);
  Vector mu(n), sigma(n);
  for (int i = 0; i < n; ++i) {
    mu(i) = 1.0f / (1.0f + std::exp(-out(i, 0)));
    sigma(i) = static_cast<float>(kMinSigma) + 0.5f * Softplus(out(i, 1));
  }
  return {mu, sigma};
}

Status WriteWeights(const std::vector<std::vector<NamedTensor>>& members, const std::string& path) {
  if (members.empty() || members.size() > static_cast<size_t>(kMaxMembersInFile)) {
    return InvalidArgumentError("a weight file holds 1 to 8 networks");
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return InternalError("cannot write " + path);
  auto put = [&out](const auto& v) { out.write(reinterpret_cast<const char*>(&v), sizeof v); };
  out.write(kMagic, sizeof kMagic);
  put(static_cast<uint32_t>(members.size()));
  for (const auto& tensors : members) {
    put(static_cast<uint32_t>(tensors.size()));
    for (const NamedTensor& t : tensors) {
      put(static_cast<uint16_t>(t.name.size()));
      out.write(t.name.data(), static_cast<std::streamsize>(t.name.size()));
      put(static_cast<uint8_t>(t.shape.size()));
      for (int64_t d : t.shape) put(d);
      out.write(reinterpret_cast<const char*>(t.values.data()),
                static_cast<std::streamsize>(t.values.size() * sizeof(float)));
    }
  }
  out.close();
  if (!out) return InternalError("cannot write " + path);
  return OkStatus();
}

StatusOr<std::vector<DenseNet>> ReadWeights(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return InvalidArgumentError("no filter weight file at '" + path + "'");
  }
  const auto size = std::filesystem::file_size(path, ec);
  auto unreadable = [&](const std::string& why) {
    return InvalidArgumentError("'" + path + "' is not a readable filter weight file: " + why);
  };
  if (ec || size > kMaxFileBytes) return unreadable("larger than 64 MiB");
  std::ifstream in(path, std::ios::binary);
  std::string bytes(static_cast<size_t>(size), '\0');
  if (!in.read(bytes.data(), static_cast<std::streamsize>(size))) return unreadable("unreadable");
  Reader r(std::move(bytes));
  std::string magic;
  if (!r.ReadBytes(sizeof kMagic, &magic) || magic != std::string(kMagic, sizeof kMagic)) {
    return unreadable("not NPFKCTW1");
  }
  uint32_t members = 0;
  if (!r.Read(&members) || members < 1 || members > kMaxMembersInFile) {
    return unreadable("it names no or too many networks (1 to 8)");
  }
  std::vector<DenseNet> out;
  for (uint32_t m = 0; m < members; ++m) {
    uint32_t count = 0;
    if (!r.Read(&count) || count > kMaxTensors) return unreadable("a bad tensor count");
    std::vector<NamedTensor> tensors(count);
    for (NamedTensor& t : tensors) {
      uint16_t name_length = 0;
      uint8_t rank = 0;
      if (!r.Read(&name_length) || name_length > kMaxName || !r.ReadBytes(name_length, &t.name) ||
          !r.Read(&rank) || rank < 1 || rank > kMaxRank) {
        return unreadable("a bad tensor head");
      }
      int64_t values = 1;
      for (int k = 0; k < rank; ++k) {
        int64_t d = 0;
        if (!r.Read(&d) || d < 1 || d > kMaxValues || values * d > kMaxValues) {
          return unreadable("tensor '" + t.name.substr(0, 64) + "' has a bad shape");
        }
        t.shape.push_back(d);
        values *= d;
      }
      if (!r.ReadFloats(static_cast<size_t>(values), &t.values)) return unreadable("truncated");
    }
    auto net = DenseNet::FromTensors(tensors);
    if (!net.ok()) return unreadable(net.status().message());
    out.push_back(*std::move(net));
  }
  if (!r.AtEnd()) return unreadable("bytes past the last network");
  return out;
}

}  // namespace npfkct::filter
