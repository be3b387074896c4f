// The filter's network for inference without libtorch: the forward pass of NpNet (network.h)
// in Eigen, over weights read from a plain weight file (.npw). A build without libtorch plans
// with it; with libtorch, `npfkct-train export` writes the .npw of a .pt model and a test checks
// that both give the same predictions. Internal to npfkct_filter.
//
// The .npw file, little-endian: the 8 bytes "NPFKCTW1", a uint32 member count (1 to 8), then per
// member a uint32 tensor count and per tensor: a uint16 name length and the name, a uint8 rank,
// the int64 dimensions, and the float32 values. Every tensor of NpNet must be there with its
// shape (the names of torch's named_parameters()); nothing else may be.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/common/status.h"

namespace npfkct::filter {

/// A named tensor of a weight file: its dimensions and its values, row-major.
struct NamedTensor {
  std::string name;
  std::vector<int64_t> shape;
  std::vector<float> values;
};

/// Writes networks' tensors as a weight file.
Status WriteWeights(const std::vector<std::vector<NamedTensor>>& members, const std::string& path);

/// One network for inference. Matrices are row-major in the sense of torch: rows are items.
class DenseNet {
 public:
  using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using Vector = Eigen::RowVectorXf;

  /// The network of `tensors`; INVALID_ARGUMENT naming a tensor that is missing, extra or of
  /// another shape.
  static StatusOr<DenseNet> FromTensors(const std::vector<NamedTensor>& tensors);

  /// points (kPoints x kPointDim), image (kImageChannels x kImageSize x kImageSize) -> kHidden.
  Vector EncodeScene(const float* points, const float* image) const;
  /// queries (n x kQueryDim) -> n x kHidden.
  Matrix EncodeQuery(const float* queries, int n) const;
  /// The mean of the latent distribution given encoded context queries and their scores.
  Vector LatentMean(const Vector& scene, const Matrix& xc, const float* yc) const;
  /// mu and sigma of each target (rows of xt, encoded).
  std::pair<Vector, Vector> Decode(const Vector& scene, const Matrix& xc, const float* yc,
                                   const Matrix& xt, const Vector& z) const;

  struct Linear {
    Matrix weight;  // out x in
    Vector bias;
    Matrix Apply(const Matrix& x) const;
  };
  struct Conv {
    int in = 0, out = 0, kernel = 0, stride = 1, padding = 0;
    Matrix weight;  // out x (in * kernel * kernel)
    Vector bias;
  };
  struct Attention {
    Linear wq, wk, wv, wo;
    Vector norm_weight, norm_bias;
    bool residual = false;
    Matrix Apply(const Matrix& q, const Matrix& k, const Matrix& v) const;
  };

 private:
  Matrix Deterministic(const Vector& scene, const Matrix& xc, const float* yc,
                       const Matrix& xt) const;

  std::vector<Linear> point_mlp_, scene_mlp_, query_mlp_, latent_mlp_, det_mlp_, decoder_;
  std::vector<Conv> cnn_;
  Linear image_fc_, latent_out_;
  Attention latent_self_, det_self_, cross_;
};

/// The networks of a weight file; missing, truncated or foreign files are INVALID_ARGUMENT
/// saying why.
StatusOr<std::vector<DenseNet>> ReadWeights(const std::string& path);

}  // namespace npfkct::filter
