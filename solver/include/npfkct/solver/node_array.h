// Storage for the nodes of a search tree that grows in bounded steps.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

namespace npfkct {

/// An indexed array of tree nodes kept in blocks of at most 2^kLog2Block elements. Appending
/// allocates at most one block's worth at a time (a block doubles up to its full size, then the
/// next block starts), where a single vector would move the whole array into one twice its size:
/// a search stopped by a heap bound between simulations (TerminationCondition::StopAtLimit)
/// overshoots it by a block, not by the tree. Indices are stable; references are not (a block
/// still below its full size may move when it grows).
template <class T, int kLog2Block = 12>
class NodeArray {
 public:
  static constexpr size_t kBlock = size_t{1} << kLog2Block;

  NodeArray() = default;
  NodeArray(const NodeArray&) = default;
  NodeArray& operator=(const NodeArray&) = default;
  /// Takes `other`'s blocks (no element moves) and leaves it empty.
  NodeArray(NodeArray&& other) noexcept
      : blocks_(std::move(other.blocks_)), size_(std::exchange(other.size_, 0)) {
    other.blocks_.clear();
  }
  NodeArray& operator=(NodeArray&& other) noexcept {
    if (this != &other) {
      blocks_ = std::move(other.blocks_);
      other.blocks_.clear();
      size_ = std::exchange(other.size_, 0);
    }
    return *this;
  }

  /// Element `i`, for i < size().
  T& operator[](size_t i) { return blocks_[i >> kLog2Block][i & (kBlock - 1)]; }
  const T& operator[](size_t i) const { return blocks_[i >> kLog2Block][i & (kBlock - 1)]; }

  /// Number of elements.
  size_t size() const { return size_; }
  /// Whether there are none.
  bool empty() const { return size_ == 0; }
  /// The last element; the array must not be empty.
  T& back() { return (*this)[size_ - 1]; }
  const T& back() const { return (*this)[size_ - 1]; }

  /// Appends an element constructed from `args` and returns it.
  template <class... Args>
  T& emplace_back(Args&&... args) {
    std::vector<T>& b = BlockWithRoom();
    b.emplace_back(std::forward<Args>(args)...);
    ++size_;
    return b.back();
  }
  /// Appends `v`.
  void push_back(T v) { emplace_back(std::move(v)); }

  /// Drops every element and gives their memory back.
  void clear() {
    blocks_.clear();
    blocks_.shrink_to_fit();
    size_ = 0;
  }

 private:
  // The last block, with room for one more element: a new block when the last is full, the last
  // grown to at most twice its capacity (never past kBlock) when it has none left.
  std::vector<T>& BlockWithRoom() {
    if (blocks_.empty() || blocks_.back().size() == kBlock) blocks_.emplace_back();
    std::vector<T>& b = blocks_.back();
    if (b.size() == b.capacity()) {
      const size_t grown = b.capacity() < 8 ? 8 : 2 * b.capacity();
      b.reserve(grown < kBlock ? grown : kBlock);
    }
    return b;
  }

  std::vector<std::vector<T>> blocks_;
  size_t size_ = 0;
};

}  // namespace npfkct
