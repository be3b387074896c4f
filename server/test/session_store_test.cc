// The directory session store against a hostile state directory: checksums, size caps, FIFOs,
// symbolic links, planted temporary files, versions.
#include "npfkct/server/session_store.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"

namespace npfkct::server {
namespace {

namespace fs = std::filesystem;

api::SessionRecord Record(const std::string& id) {
  api::WorldSpec spec;
  spec.furniture.push_back({"table", api::Box{{1.5, 0, 0.4}, 0.0, {0.8, 1.2, 0.8}}, true});
  spec.base_regions.push_back({{0.2, -0.6}, {0.6, 0.6}});
  api::SessionRecord r;
  r.id = id;
  r.planner.name = "kct";
  r.world = api::BuildWorld(spec, api::Limits()).value();
  return r;
}

// A grey PNG of `side` x `side` pixels of value `shade`.
std::string Png(int side, unsigned char shade) {
  return api::EncodePng(cv::Mat(side, side, CV_8UC1, cv::Scalar(shade))).value();
}

std::string ReadFile(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

class DirectoryStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("npfkct-store-" + std::to_string(getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::unique_ptr<DirectoryStore> Open() {
    auto s = DirectoryStore::Open(dir_.string(), api::Limits(), 1 << 20);
    EXPECT_TRUE(s.ok()) << s.status().ToString();
    return std::move(s).value();
  }
  fs::path dir_;
};

const std::string kA(32, 'a'), kB(32, 'b'), kC(32, 'c'), kD(32, 'd'), kE(32, 'e'), kF(32, 'f');

TEST_F(DirectoryStoreTest, SavesLoadsAndVersions) {
  auto store = Open();
  auto v1 = store->Save(Record(kA), 0);
  ASSERT_TRUE(v1.ok()) << v1.status().ToString();
  EXPECT_EQ(*v1, 1);
  auto v2 = store->Save(Record(kA), *v1);
  ASSERT_TRUE(v2.ok());
  EXPECT_EQ(*v2, 2);
  // A save that names an old version lost a race: ABORTED (optimistic concurrency).
  EXPECT_EQ(store->Save(Record(kA), 1).status().code(), StatusCode::kAborted);
  store.reset();  // the store holds the directory's lock
  auto reopened = Open();
  auto loaded = reopened->Load(kA);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_EQ(loaded->version, 2);
  EXPECT_EQ(loaded->record.planner.name, "kct");
  EXPECT_EQ(reopened->List(10).value(), std::vector<std::string>{kA});
  ASSERT_TRUE(reopened->Delete(kA).ok());
  EXPECT_TRUE(reopened->List(10).value().empty());
  EXPECT_EQ(reopened->Load(kA).status().code(), StatusCode::kNotFound);
}

TEST_F(DirectoryStoreTest, TargetPhotosAreWrittenOnceAndRestored) {
  // Every plan and observation saves the session: eight large photos in each snapshot made every
  // 150-byte request rewrite and fsync 31 MB.
  api::SessionRecord r = Record(kA);
  r.target.description = "mug";
  r.target.photos = {Png(16, 40), Png(24, 200)};
  const fs::path photos = dir_ / (kA + ".photos"), snap = dir_ / (kA + ".snap");
  struct stat first {};
  {
    auto store = Open();
    ASSERT_TRUE(store->Save(r, 0).ok());
    ASSERT_EQ(::stat(photos.c_str(), &first), 0);
    for (int v = 1; v <= 3; ++v) ASSERT_TRUE(store->Save(r, v).ok()) << v;
    struct stat later {};
    ASSERT_EQ(::stat(photos.c_str(), &later), 0);
    EXPECT_EQ(later.st_ino, first.st_ino);  // never written again
    EXPECT_EQ(later.st_mtim.tv_nsec, first.st_mtim.tv_nsec);
    const std::string snapshot = ReadFile(snap);
    EXPECT_NE(snapshot.find("photosKeptApart"), std::string::npos);
    EXPECT_EQ(snapshot.find("\"photos\""), std::string::npos);
  }
  {
    auto store = Open();
    auto loaded = store->Load(kA);
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_EQ(loaded->version, 4);
    EXPECT_EQ(loaded->record.target.description, "mug");
    EXPECT_EQ(loaded->record.target.photos, r.target.photos);
    // Saved after a load: still named, not written.
    ASSERT_TRUE(store->Save(loaded->record, 4).ok());
    struct stat later {};
    ASSERT_EQ(::stat(photos.c_str(), &later), 0);
    EXPECT_EQ(later.st_ino, first.st_ino);
  }
  // Photos that are not the ones the snapshot names, or none: DATA_LOSS, never a crash.
  const std::string good = ReadFile(photos);
  for (const std::string& bad : {good.substr(0, good.size() / 2), good + " ", std::string()}) {
    if (bad.empty()) {
      fs::remove(photos);
    } else {
      std::ofstream(photos, std::ios::binary | std::ios::trunc) << bad;
    }
    auto store = Open();
    EXPECT_EQ(store->Load(kA).status().code(), StatusCode::kDataLoss) << bad.size();
  }
  // One past the store's cap (a sparse 2 GiB file) is refused by its size, unread.
  std::ofstream(photos, std::ios::binary | std::ios::trunc) << good;
  fs::resize_file(photos, 2ull << 30);
  {
    auto store = Open();
    const Status huge = store->Load(kA).status();
    EXPECT_EQ(huge.code(), StatusCode::kDataLoss);
    EXPECT_NE(huge.message().find("more than the cap"), std::string::npos) << huge.ToString();
  }
  std::ofstream(photos, std::ios::binary | std::ios::trunc) << good;
  // A snapshot of before, with its photos inside, loads; its next save keeps them apart.
  api::SessionRecord b = Record(kB);
  b.target.photos = {Png(32, 90)};
  std::ofstream(dir_ / (kB + ".snap"), std::ios::binary) << EncodeSnapshot(b, 1);
  // An orphan photos file (a create or delete cut short) goes when the store opens.
  std::ofstream(dir_ / (kC + ".photos"), std::ios::binary) << good;
  auto store = Open();
  EXPECT_FALSE(fs::exists(dir_ / (kC + ".photos")));
  auto inline_b = store->Load(kB);
  ASSERT_TRUE(inline_b.ok()) << inline_b.status().ToString();
  EXPECT_EQ(inline_b->record.target.photos, b.target.photos);
  EXPECT_FALSE(fs::exists(dir_ / (kB + ".photos")));
  ASSERT_TRUE(store->Save(inline_b->record, 1).ok());
  EXPECT_TRUE(fs::exists(dir_ / (kB + ".photos")));
  auto reloaded = store->Load(kB);
  ASSERT_TRUE(reloaded.ok()) << reloaded.status().ToString();
  EXPECT_EQ(reloaded->record.target.photos, b.target.photos);
  // Delete removes both files.
  ASSERT_TRUE(store->Delete(kA).ok());
  EXPECT_FALSE(fs::exists(photos));
  EXPECT_FALSE(fs::exists(snap));
  EXPECT_EQ(store->List(10).value(), std::vector<std::string>{kB});
}

TEST_F(DirectoryStoreTest, ADirectoryInUseIsRefusedAndItsTemporaryFilesKept) {
  // Two stores on one directory would each trust their own versions and overwrite each other's
  // snapshots; the second's start would remove the first's save in progress.
  auto store = Open();
  const fs::path in_progress = dir_ / (kA + ".snap.tmp.0123456789abcdef");
  std::ofstream(in_progress) << "a save in progress";
  auto second = DirectoryStore::Open(dir_.string(), api::Limits(), 1 << 20);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(second.status().message().find(dir_.string() + "' is in use"), std::string::npos)
      << second.status().ToString();
  EXPECT_TRUE(fs::exists(in_progress));
  store.reset();  // the lock goes with the store
  auto third = Open();
  EXPECT_FALSE(fs::exists(in_progress));
  // A planted symbolic link in place of the lock file is not followed.
  third.reset();
  fs::remove(dir_ / ".lock");
  fs::create_symlink(dir_ / "elsewhere", dir_ / ".lock");
  auto linked = DirectoryStore::Open(dir_.string(), api::Limits(), 1 << 20);
  ASSERT_FALSE(linked.ok());
  EXPECT_EQ(linked.status().code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(dir_ / "elsewhere"));
}

TEST_F(DirectoryStoreTest, ACorruptedOrTruncatedSnapshotIsDataLossNotACrash) {
  auto store = Open();
  ASSERT_TRUE(store->Save(Record(kA), 0).ok());
  ASSERT_TRUE(store->Save(Record(kB), 0).ok());
  const fs::path a = dir_ / (kA + ".snap");
  {
    std::fstream f(a, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(fs::file_size(a) / 2));
    f.put('#');  // one byte flipped in the middle
  }
  fs::resize_file(dir_ / (kB + ".snap"), fs::file_size(dir_ / (kB + ".snap")) - 10);
  store.reset();
  auto reopened = Open();
  EXPECT_EQ(reopened->Load(kA).status().code(), StatusCode::kDataLoss);
  EXPECT_EQ(reopened->Load(kB).status().code(), StatusCode::kDataLoss);
}

TEST_F(DirectoryStoreTest, HostileEntriesAreSkippedWithoutHangingOrFollowingLinks) {
  auto store = Open();
  ASSERT_TRUE(store->Save(Record(kA), 0).ok());
  // A FIFO under a snapshot's name (opening it for reading would block), a symbolic link to a
  // system file, a directory, a sparse file of 2 GB, and a planted temporary symbolic link.
  ASSERT_EQ(::mkfifo((dir_ / (kB + ".snap")).c_str(), 0600), 0);
  fs::create_symlink("/etc/passwd", dir_ / (kC + ".snap"));
  fs::create_directory(dir_ / (kD + ".snap"));
  {
    std::ofstream(dir_ / (kE + ".snap")) << "x";
    fs::resize_file(dir_ / (kE + ".snap"), 2ull << 30);
  }
  const fs::path victim = dir_ / "victim.txt";
  std::ofstream(victim) << "keep me";
  fs::create_symlink(victim, dir_ / (kF + ".snap.tmp.0123456789abcdef"));
  std::ofstream(dir_ / "README") << "not a snapshot";

  const auto t0 = std::chrono::steady_clock::now();
  store.reset();
  auto reopened = Open();  // removes the planted temporary link (the link, not its target)
  EXPECT_FALSE(fs::exists(fs::symlink_status(dir_ / (kF + ".snap.tmp.0123456789abcdef"))));
  EXPECT_EQ(std::ifstream(victim).rdbuf() != nullptr, true);
  std::string kept;
  std::getline(std::ifstream(victim), kept);
  EXPECT_EQ(kept, "keep me");
  // Only regular files are listed; each hostile one fails to load without blocking.
  const auto ids = reopened->List(100).value();
  EXPECT_EQ(ids, (std::vector<std::string>{kA, kE}));
  for (const std::string& id : {kB, kC, kD, kE}) {
    auto r = reopened->Load(id);
    EXPECT_FALSE(r.ok()) << id;
    EXPECT_EQ(r.status().code(), StatusCode::kDataLoss) << id << " " << r.status().ToString();
  }
  EXPECT_TRUE(reopened->Load(kA).ok());
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
  // A save to the name of a planted link replaces the link; the file it pointed to is intact.
  fs::remove(dir_ / (kC + ".snap"));
  fs::create_symlink(victim, dir_ / (kC + ".snap"));
  ASSERT_TRUE(reopened->Save(Record(kC), 0).ok());
  EXPECT_FALSE(fs::is_symlink(dir_ / (kC + ".snap")));
  std::getline(std::ifstream(victim), kept);
  EXPECT_EQ(kept, "keep me");
  EXPECT_EQ(reopened->List(1).value().size(), 1u);  // the limit holds
}

TEST(MemoryStore, KeepsNothing) {
  auto store = MakeMemoryStore();
  EXPECT_EQ(store->Save(Record(kA), 0).value(), 1);
  EXPECT_TRUE(store->List(10).value().empty());
  EXPECT_EQ(store->Load(kA).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace npfkct::server
