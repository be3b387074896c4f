#include "npfkct/solver/clustering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>

namespace npfkct {
namespace {

std::vector<ActionVec> Blobs(const std::vector<ActionVec>& centers, int per, double sd, Rng& rng) {
  std::vector<ActionVec> pts;
  for (const auto& c : centers) {
    for (int i = 0; i < per; ++i) {
      ActionVec p = c;
      for (int d = 0; d < p.size(); ++d) p[d] += sd * rng.Normal();
      pts.push_back(p);
    }
  }
  return pts;
}

TEST(KMeansTest, FindsSeparatedBlobs) {
  BoxSpace box(MakeActionVec({-10, -10}), MakeActionVec({10, 10}));
  Rng rng(1);
  const std::vector<ActionVec> centers = {MakeActionVec({-5, -5}), MakeActionVec({5, -5}),
                                          MakeActionVec({0, 6})};
  auto pts = Blobs(centers, 100, 0.3, rng);
  auto clusters = KMeans(box, pts, 3, rng);
  ASSERT_EQ(clusters.size(), 3u);
  for (const auto& c : centers) {
    double best = 1e9;
    for (const auto& k : clusters) best = std::min(best, box.Distance(c, k.center));
    EXPECT_LT(best, 0.15);
  }
  size_t members = 0;
  for (const auto& k : clusters) {
    members += k.members.size();
    for (int m : k.members) EXPECT_LE(box.Distance(pts[m], k.center), k.radius + 1e-12);
  }
  EXPECT_EQ(members, pts.size());
}

TEST(KMeansTest, FewerDistinctPointsThanK) {
  BoxSpace box(MakeActionVec({0}), MakeActionVec({1}));
  Rng rng(2);
  std::vector<ActionVec> pts(10, MakeActionVec({0.5}));
  auto clusters = KMeans(box, pts, 3, rng);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0].radius, 0.0);
  EXPECT_TRUE(KMeans(box, {}, 3, rng).empty());
}

TEST(KMeansTest, PeriodicClusterAcrossTheSeam) {
  BoxSpace box(MakeActionVec({0}), MakeActionVec({2 * std::numbers::pi}));
  box.SetPeriodic(0);
  Rng rng(3);
  std::vector<ActionVec> pts;
  for (int i = 0; i < 50; ++i) pts.push_back(MakeActionVec({0.05 * i / 50.0}));
  for (int i = 0; i < 50; ++i)
    pts.push_back(MakeActionVec({2 * std::numbers::pi - 0.05 * i / 50.0}));
  auto clusters = KMeans(box, pts, 1, rng);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_LT(box.Distance(clusters[0].center, MakeActionVec({0.0})), 0.01);
  EXPECT_LT(clusters[0].radius, 0.06);
}

TEST(ElbowTest, PicksTheBend) {
  EXPECT_EQ(ElbowK({100, 40, 10, 8, 7, 6}), 3);
  EXPECT_EQ(ElbowK({100, 20, 15, 12, 10}), 2);
  EXPECT_EQ(ElbowK({10, 5}), 1);
  EXPECT_EQ(ElbowK({0, 0, 0}), 1);
}

TEST(ElbowTest, ClusterByElbowRecoversTheBlobCount) {
  BoxSpace box(MakeActionVec({-10, -10, -10}), MakeActionVec({10, 10, 10}));
  Rng rng(4);
  auto pts = Blobs({MakeActionVec({-5, 0, 0}), MakeActionVec({5, 0, 0}), MakeActionVec({0, 5, 5}),
                    MakeActionVec({0, -5, 5})},
                   80, 0.4, rng);
  auto clusters = ClusterByElbow(box, pts, 8, rng);
  EXPECT_EQ(clusters.size(), 4u);
  // A search that must stop ends the runs after k = 1 (one Lloyd iteration): the elbow of what
  // there is.
  int polls = 0;
  auto cut = ClusterByElbow(box, pts, 8, rng, [&polls] { return ++polls > 0; });
  EXPECT_EQ(cut.size(), 1u);
  EXPECT_EQ(polls, 2);  // after k-means' first iteration, then after k = 1
  EXPECT_EQ(cut[0].members.size(), pts.size());
}

}  // namespace
}  // namespace npfkct
