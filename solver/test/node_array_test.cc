// NodeArray: indexing across blocks, growth that never moves more than a block's elements at once
// (a single vector moves the whole array when it doubles), and elements destroyed on clear.
#include "npfkct/solver/node_array.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <string>

namespace npfkct {
namespace {

// Counts moves and live instances.
struct Counted {
  static inline int moves = 0;
  static inline int live = 0;
  int value = 0;
  explicit Counted(int v) : value(v) { ++live; }
  Counted(const Counted& o) : value(o.value) { ++live; }
  Counted(Counted&& o) noexcept : value(o.value) {
    ++moves;
    ++live;
  }
  ~Counted() { --live; }
};

TEST(NodeArrayTest, IndexesEveryElementAcrossBlocks) {
  NodeArray<std::string, 3> a;  // blocks of 8
  EXPECT_TRUE(a.empty());
  for (int i = 0; i < 100; ++i) {
    std::string& added = a.emplace_back(std::to_string(i));
    EXPECT_EQ(added, std::to_string(i));
  }
  a.push_back("last");
  ASSERT_EQ(a.size(), 101u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(a[i], std::to_string(i)) << i;
  EXPECT_EQ(a.back(), "last");
  a[42] = "changed";
  const NodeArray<std::string, 3>& c = a;
  EXPECT_EQ(c[42], "changed");
  EXPECT_EQ(c[41], "41");
}

TEST(NodeArrayTest, OneAppendMovesAtMostHalfABlock) {
  Counted::moves = 0;
  Counted::live = 0;
  {
    NodeArray<Counted, 4> a;  // blocks of 16
    int most = 0;
    for (int i = 0; i < 1000; ++i) {
      const int before = Counted::moves;
      a.emplace_back(i);
      most = std::max(most, Counted::moves - before);
    }
    // The last block doubles from 8 to 16 elements at most; a vector of 1,000 would have moved
    // 512 elements in one append.
    EXPECT_LE(most, 8);
    EXPECT_GT(most, 0);
    for (int i = 0; i < 1000; ++i) ASSERT_EQ(a[i].value, i);
    EXPECT_EQ(Counted::live, 1000);
    a.clear();
    EXPECT_EQ(Counted::live, 0);
    EXPECT_EQ(a.size(), 0u);
    a.emplace_back(7);
    EXPECT_EQ(a[0].value, 7);
  }
  EXPECT_EQ(Counted::live, 0);
}

TEST(NodeArrayTest, MovingTheArrayMovesNoElement) {
  NodeArray<Counted, 4> a;
  for (int i = 0; i < 100; ++i) a.emplace_back(i);
  const int before = Counted::moves;
  NodeArray<Counted, 4> b = std::move(a);
  EXPECT_EQ(a.size(), 0u);  // NOLINT(bugprone-use-after-move): moved-from is empty
  EXPECT_EQ(b.size(), 100u);
  a = std::move(b);
  EXPECT_EQ(b.size(), 0u);  // NOLINT(bugprone-use-after-move)
  EXPECT_EQ(Counted::moves, before);
  EXPECT_EQ(a.size(), 100u);
  EXPECT_EQ(a[99].value, 99);
}

}  // namespace
}  // namespace npfkct
