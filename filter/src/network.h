// The attentive latent neural process of the filter (paper section 4.1, figure 15; Kim et al.
// 2019). Internal to npfkct_filter: libtorch never reaches a public header.
#pragma once

#include <torch/torch.h>

#include <random>
#include <string>
#include <utility>
#include <vector>

#include "dense_net.h"
#include "net_shape.h"
#include "npfkct/common/status.h"
#include "npfkct/filter/dataset.h"

namespace npfkct::filter {


/// Multi-head scaled dot-product attention; with `residual`, the output is added to the query and
/// layer-normalised.
struct AttentionImpl : torch::nn::Module {
  AttentionImpl(int dim, int heads, bool residual);
  torch::Tensor forward(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& v);

  torch::nn::Linear wq{nullptr}, wk{nullptr}, wv{nullptr}, wo{nullptr};
  torch::nn::LayerNorm norm{nullptr};
  int heads;
  bool residual;
};
TORCH_MODULE(Attention);

/// The network: scene encoders (PointNet over the object cloud, a CNN over the odds image), the
/// query encoder, the latent path and the deterministic path with self-attention over the context,
/// cross-attention from the targets, and the decoder of mu and sigma.
struct NpNetImpl : torch::nn::Module {
  NpNetImpl();
  /// points [B, kPoints, kPointDim], image [B, C, S, S] -> [B, kHidden].
  torch::Tensor EncodeScene(const torch::Tensor& points, const torch::Tensor& image);
  /// queries [B, N, kQueryDim] -> [B, N, kHidden].
  torch::Tensor EncodeQuery(const torch::Tensor& queries);
  /// The latent distribution (mean, std) [B, kLatent] of encoded queries with scores [B, N, 1].
  std::pair<torch::Tensor, torch::Tensor> Latent(const torch::Tensor& scene,
                                                 const torch::Tensor& xc, const torch::Tensor& yc);
  /// The deterministic representation [B, Nt, kHidden] of each target.
  torch::Tensor Deterministic(const torch::Tensor& scene, const torch::Tensor& xc,
                              const torch::Tensor& yc, const torch::Tensor& xt);
  /// mu and sigma [B, Nt] of each target given z [B, kLatent].
  std::pair<torch::Tensor, torch::Tensor> Decode(const torch::Tensor& scene,
                                                 const torch::Tensor& xt, const torch::Tensor& r,
                                                 const torch::Tensor& z);

  torch::nn::Sequential point_mlp{nullptr}, cnn{nullptr}, scene_mlp{nullptr}, query_mlp{nullptr};
  torch::nn::Linear image_fc{nullptr};
  torch::nn::Sequential latent_mlp{nullptr}, det_mlp{nullptr}, decoder{nullptr};
  Attention latent_self{nullptr}, det_self{nullptr}, cross{nullptr};
  torch::nn::Linear latent_out{nullptr};
  torch::Tensor format;
};
TORCH_MODULE(NpNet);

/// A batch of samples as tensors: context and target queries with their scores.
struct Batch {
  torch::Tensor points, image, xc, yc, xt, yt;
};

/// The batch of `samples` (indices into data): with `shuffle`, each sample's queries are permuted
/// by `gen` and the targets are all queries; otherwise the first `context` are the context and the
/// rest the targets.
Batch MakeBatch(const Dataset& data, const std::vector<int>& samples, int context, bool shuffle,
                std::mt19937_64* gen);

/// The negative log-likelihood per target of N(y; mu, sigma).
torch::Tensor GaussianNll(const torch::Tensor& mu, const torch::Tensor& sigma,
                          const torch::Tensor& y);

/// Predictions with z at the mean of the context's latent distribution: mu, sigma [B, Nt].
std::pair<torch::Tensor, torch::Tensor> PredictBatch(NpNet& net, const Batch& b);

/// The most networks one model file holds.
inline constexpr int kMaxMembers = 8;

/// Saves the weights with the format marker.
Status SaveNet(NpNet& net, const std::string& path);
/// Saves 1 to kMaxMembers networks as one model file (an ensemble): their count, then each
/// network's weights with its format marker.
Status SaveMembers(const std::vector<NpNet>& members, const std::string& path);
/// Loads the networks of a model file: one saved by SaveNet, or those saved by SaveMembers.
/// Missing, corrupt or foreign files are INVALID_ARGUMENT.
StatusOr<std::vector<NpNet>> LoadMembers(const std::string& path);

/// A network's parameters and format marker as named tensors (torch's names), for a weight file
/// (dense_net.h).
std::vector<NamedTensor> ExportTensors(NpNet& net);

}  // namespace npfkct::filter
