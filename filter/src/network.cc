#include "network.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

namespace npfkct::filter {
namespace {

torch::nn::Sequential Mlp(const std::vector<int>& sizes, bool relu_last = false) {
  torch::nn::Sequential seq;
  for (size_t i = 0; i + 1 < sizes.size(); ++i) {
    seq->push_back(torch::nn::Linear(sizes[i], sizes[i + 1]));
    if (i + 2 < sizes.size() || relu_last) seq->push_back(torch::nn::ReLU());
  }
  return seq;
}

torch::Tensor FormatMarker() {
  return torch::tensor(
      {int64_t{kFormatVersion}, int64_t{kPoints}, int64_t{kPointDim}, int64_t{kImageSize},
       int64_t{kImageChannels}, int64_t{kQueryDim}, int64_t{kHidden}, int64_t{kLatent}},
      torch::kInt64);
}

// [B, H] -> [B, N, H].
torch::Tensor Spread(const torch::Tensor& scene, int64_t n) {
  return scene.unsqueeze(1).expand({scene.size(0), n, scene.size(1)});
}

}  // namespace

AttentionImpl::AttentionImpl(int dim, int heads_in, bool residual_in)
    : heads(heads_in), residual(residual_in) {
  wq = register_module("wq", torch::nn::Linear(dim, dim));
  wk = register_module("wk", torch::nn::Linear(dim, dim));
  wv = register_module("wv", torch::nn::Linear(dim, dim));
  wo = register_module("wo", torch::nn::Linear(dim, dim));
  norm = register_module("norm", torch::nn::LayerNorm(torch::nn::LayerNormOptions({dim})));
}

torch::Tensor AttentionImpl::forward(const torch::Tensor& q, const torch::Tensor& k,
                                     const torch::Tensor& v) {
  const int64_t b = q.size(0), nq = q.size(1), nk = k.size(1), dim = q.size(2);
  const int64_t d = dim / heads;
  auto split = [&](const torch::Tensor& t, int64_t n) {
    return t.view({b, n, heads, d}).transpose(1, 2);  // [B, h, N, d]
  };
  const torch::Tensor qh = split(wq->forward(q), nq);
  const torch::Tensor kh = split(wk->forward(k), nk);
  const torch::Tensor vh = split(wv->forward(v), nk);
  const torch::Tensor w = torch::softmax(torch::matmul(qh, kh.transpose(2, 3)) / std::sqrt(d), -1);
  torch::Tensor out = torch::matmul(w, vh).transpose(1, 2).reshape({b, nq, dim});
  out = wo->forward(out);
  return residual ? norm->forward(q + out) : out;
}

NpNetImpl::NpNetImpl() {
  point_mlp = register_module("point_mlp", Mlp({kPointDim, 32, kHidden}, true));
  cnn = register_module(
      "cnn",
      torch::nn::Sequential(
          torch::nn::Conv2d(torch::nn::Conv2dOptions(kImageChannels, 16, 5).stride(2).padding(2)),
          torch::nn::ReLU(),
          torch::nn::Conv2d(torch::nn::Conv2dOptions(16, 32, 3).stride(2).padding(1)),
          torch::nn::ReLU(),
          torch::nn::Conv2d(torch::nn::Conv2dOptions(32, 32, 3).stride(2).padding(1)),
          torch::nn::ReLU()));
  const int flat = 32 * (kImageSize / 8) * (kImageSize / 8);
  image_fc = register_module("image_fc", torch::nn::Linear(flat, kHidden));
  scene_mlp = register_module("scene_mlp", Mlp({2 * kHidden, kHidden}, true));
  query_mlp = register_module("query_mlp", Mlp({kQueryDim, kHidden, kHidden}));
  latent_mlp = register_module("latent_mlp", Mlp({2 * kHidden + 1, kHidden, kHidden}));
  det_mlp = register_module("det_mlp", Mlp({2 * kHidden + 1, kHidden, kHidden}));
  latent_self = register_module("latent_self", Attention(kHidden, kHeads, true));
  det_self = register_module("det_self", Attention(kHidden, kHeads, true));
  cross = register_module("cross", Attention(kHidden, kHeads, false));
  latent_out = register_module("latent_out", torch::nn::Linear(kHidden, 2 * kLatent));
  decoder = register_module("decoder", Mlp({3 * kHidden + kLatent, kHidden, kHidden, 2}));
  format = register_buffer("npfkct_filter_format", FormatMarker());
}

torch::Tensor NpNetImpl::EncodeScene(const torch::Tensor& points, const torch::Tensor& image) {
  const torch::Tensor p = std::get<0>(point_mlp->forward(points).max(1));
  const torch::Tensor i = torch::relu(image_fc->forward(cnn->forward(image).flatten(1)));
  return scene_mlp->forward(torch::cat({p, i}, 1));
}

torch::Tensor NpNetImpl::EncodeQuery(const torch::Tensor& queries) {
  return query_mlp->forward(queries);
}

std::pair<torch::Tensor, torch::Tensor> NpNetImpl::Latent(const torch::Tensor& scene,
                                                          const torch::Tensor& xc,
                                                          const torch::Tensor& yc) {
  torch::Tensor s = latent_mlp->forward(torch::cat({xc, yc, Spread(scene, xc.size(1))}, 2));
  s = latent_self->forward(s, s, s).mean(1);
  const torch::Tensor out = latent_out->forward(torch::relu(s));
  const torch::Tensor mean = out.slice(1, 0, kLatent);
  const torch::Tensor std = 0.1 + 0.9 * torch::sigmoid(out.slice(1, kLatent, 2 * kLatent));
  return {mean, std};
}

torch::Tensor NpNetImpl::Deterministic(const torch::Tensor& scene, const torch::Tensor& xc,
                                       const torch::Tensor& yc, const torch::Tensor& xt) {
  torch::Tensor r = det_mlp->forward(torch::cat({xc, yc, Spread(scene, xc.size(1))}, 2));
  r = det_self->forward(r, r, r);
  return cross->forward(xt, xc, r);
}

std::pair<torch::Tensor, torch::Tensor> NpNetImpl::Decode(const torch::Tensor& scene,
                                                          const torch::Tensor& xt,
                                                          const torch::Tensor& r,
                                                          const torch::Tensor& z) {
  const int64_t n = xt.size(1);
  const torch::Tensor out =
      decoder->forward(torch::cat({xt, r, Spread(z, n), Spread(scene, n)}, 2));
  const torch::Tensor mu = torch::sigmoid(out.select(2, 0));
  const torch::Tensor sigma = kMinSigma + 0.5 * torch::softplus(out.select(2, 1));
  return {mu, sigma};
}

Batch MakeBatch(const Dataset& data, const std::vector<int>& samples, int context, bool shuffle,
                std::mt19937_64* gen) {
  const int64_t b = static_cast<int64_t>(samples.size());
  const int m = data.queries_per_sample;
  const int nt = shuffle ? m : m - context;
  Batch out;
  out.points = torch::empty({b, kPoints, kPointDim});
  out.image = torch::empty({b, kImageChannels, kImageSize, kImageSize});
  out.xc = torch::empty({b, context, kQueryDim});
  out.yc = torch::empty({b, context, 1});
  out.xt = torch::empty({b, nt, kQueryDim});
  out.yt = torch::empty({b, nt, 1});
  std::vector<int> order(m);
  for (int64_t i = 0; i < b; ++i) {
    const Sample& s = data.samples[samples[i]];
    std::copy(s.scene.points.begin(), s.scene.points.end(), out.points[i].data_ptr<float>());
    std::copy(s.scene.image.begin(), s.scene.image.end(), out.image[i].data_ptr<float>());
    std::iota(order.begin(), order.end(), 0);
    if (shuffle) std::shuffle(order.begin(), order.end(), *gen);
    float* xc = out.xc[i].data_ptr<float>();
    float* yc = out.yc[i].data_ptr<float>();
    float* xt = out.xt[i].data_ptr<float>();
    float* yt = out.yt[i].data_ptr<float>();
    for (int k = 0; k < context; ++k) {
      std::copy_n(&s.queries[static_cast<size_t>(order[k]) * kQueryDim], kQueryDim,
                  xc + k * kQueryDim);
      yc[k] = s.scores[order[k]];
    }
    for (int k = 0; k < nt; ++k) {
      const int q = shuffle ? order[k] : context + k;
      std::copy_n(&s.queries[static_cast<size_t>(q) * kQueryDim], kQueryDim, xt + k * kQueryDim);
      yt[k] = s.scores[q];
    }
  }
  return out;
}

torch::Tensor GaussianNll(const torch::Tensor& mu, const torch::Tensor& sigma,
                          const torch::Tensor& y) {
  const torch::Tensor z = (y - mu) / sigma;
  return 0.5 * z * z + torch::log(sigma) + 0.5 * std::log(2.0 * M_PI);
}

std::pair<torch::Tensor, torch::Tensor> PredictBatch(NpNet& net, const Batch& b) {
  const torch::Tensor scene = net->EncodeScene(b.points, b.image);
  const torch::Tensor xc = net->EncodeQuery(b.xc);
  const torch::Tensor xt = net->EncodeQuery(b.xt);
  const torch::Tensor z = net->Latent(scene, xc, b.yc).first;
  return net->Decode(scene, xt, net->Deterministic(scene, xc, b.yc, xt), z);
}

Status SaveNet(NpNet& net, const std::string& path) {
  try {
    torch::save(net, path);
  } catch (const c10::Error& e) {
    return InternalError("cannot save the filter model to " + path + ": " +
                         e.what_without_backtrace());
  }
  return OkStatus();
}

namespace {

constexpr char kMembersKey[] = "npfkct_filter_members";

std::string MemberKey(int i) { return "member" + std::to_string(i); }

// The format marker of a loaded network: the one this build writes.
bool CurrentFormat(const NpNet& net) {
  return net->format.defined() && net->format.numel() == FormatMarker().numel() &&
         torch::equal(net->format, FormatMarker());
}

// Whether every weight of a loaded network has the shape and type of a new one's, laid out
// densely within its storage: a file could declare a weight of any shape over a small storage.
bool WellShaped(const NpNet& net) {
  const NpNet fresh;
  auto dense = [](const torch::Tensor& t, const torch::Tensor& like) {
    return t.defined() && t.sizes() == like.sizes() && t.scalar_type() == like.scalar_type() &&
           t.is_contiguous() &&
           static_cast<size_t>(t.storage_offset() + t.numel()) * t.element_size() <=
               t.storage().nbytes();
  };
  // The same names, each tensor dense with the shape and type of the new network's.
  auto same = [&](const torch::OrderedDict<std::string, torch::Tensor>& have,
                  const torch::OrderedDict<std::string, torch::Tensor>& want) {
    if (have.size() != want.size()) return false;
    for (const auto& w : want) {
      const torch::Tensor* t = have.find(w.key());
      if (t == nullptr || !dense(*t, w.value())) return false;
    }
    return true;
  };
  return same(net->named_parameters(), fresh->named_parameters()) &&
         same(net->named_buffers(), fresh->named_buffers());
}

}  // namespace

Status SaveMembers(const std::vector<NpNet>& members, const std::string& path) {
  if (members.empty() || members.size() > static_cast<size_t>(kMaxMembers)) {
    return InvalidArgumentError("a model file holds 1 to " + std::to_string(kMaxMembers) +
                                " networks, not " + std::to_string(members.size()));
  }
  try {
    torch::serialize::OutputArchive archive;
    archive.write(kMembersKey, torch::tensor({static_cast<int64_t>(members.size())}), true);
    for (size_t i = 0; i < members.size(); ++i) {
      torch::serialize::OutputArchive member;
      members[i]->save(member);
      archive.write(MemberKey(static_cast<int>(i)), member);
    }
    archive.save_to(path);
  } catch (const c10::Error& e) {
    return InternalError("cannot save the filter model to " + path + ": " +
                         e.what_without_backtrace());
  }
  return OkStatus();
}

StatusOr<std::vector<NpNet>> LoadMembers(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return InvalidArgumentError("no filter model file at '" + path + "'");
  }
  auto unreadable = [&](const std::string& why) {
    return InvalidArgumentError("'" + path +
                                "' is not a readable filter model: " + why.substr(0, 200));
  };
  std::vector<NpNet> members;
  try {
    torch::serialize::InputArchive archive;
    archive.load_from(path);
    torch::Tensor count;
    if (!archive.try_read(kMembersKey, count, true)) {
      members.emplace_back();
      members.back()->load(archive);  // one network, as SaveNet writes it
    } else {
      if (count.numel() != 1 || count.scalar_type() != torch::kInt64) {
        return unreadable("its member count is not one integer");
      }
      const int64_t n = count.item<int64_t>();
      if (n < 1 || n > kMaxMembers) {
        return unreadable("it names " + std::to_string(n) + " networks (1 to " +
                          std::to_string(kMaxMembers) + ")");
      }
      for (int i = 0; i < n; ++i) {
        torch::serialize::InputArchive member;
        if (!archive.try_read(MemberKey(i), member)) {
          return unreadable("network " + std::to_string(i) + " is missing");
        }
        members.emplace_back();
        members.back()->load(member);
      }
    }
  } catch (const c10::Error& e) {
    return unreadable(e.what_without_backtrace());
  } catch (const std::exception& e) {
    return unreadable(e.what());
  }
  for (NpNet& net : members) {
    if (!CurrentFormat(net)) {
      return InvalidArgumentError("'" + path + "' was saved by an incompatible filter version");
    }
    if (!WellShaped(net)) return unreadable("a weight has another shape or layout than the net's");
    net->eval();
  }
  return members;
}

std::vector<NamedTensor> ExportTensors(NpNet& net) {
  std::vector<NamedTensor> out;
  auto add = [&out](const std::string& name, const torch::Tensor& t) {
    const torch::Tensor values = t.to(torch::kFloat32).contiguous();
    NamedTensor n{name, {}, {}};
    for (int64_t d : values.sizes()) n.shape.push_back(d);
    n.values.assign(values.data_ptr<float>(), values.data_ptr<float>() + values.numel());
    out.push_back(std::move(n));
  };
  for (const auto& p : net->named_parameters()) add(p.key(), p.value());
  add("npfkct_filter_format", net->format);
  return out;
}

}  // namespace npfkct::filter
