// Atomic writes and what a killed writer leaves: temporaries of dead processes are removed by the
// next write into the same folder; a group of files appears together or not at all.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <string>

#include "common/file_io.h"
#include "test_data.h"

namespace hc {
namespace {

// The id of a process that has exited (forked and reaped), as a writer killed by kill -9 leaves.
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  ::waitpid(pid, nullptr, 0);
  return pid;
}

bool present(const std::filesystem::path& p) { return std::filesystem::exists(p); }

TEST(FileIo, TemporariesOfDeadWritersAreRemovedByTheNextWrite) {
  testing::ScratchDir dir;
  const std::string dead = std::to_string(dead_pid());
  const std::string live = std::to_string(::getppid());  // the test runner's parent: alive
  // What a kill -9 left: an atomic 3MF write, a PNG, an export's staging folder with a frame.
  { std::ofstream(dir / ("part.3mf.tmp-" + dead + "-0123abcd")) << "half"; }
  { std::ofstream(dir / ("f_000001.png.tmp-" + dead + "-deadbeef")) << "half"; }
  std::filesystem::create_directory(dir / ("cam0_image.tmp-" + dead + "-00c0ffee"));
  { std::ofstream(dir / ("cam0_image.tmp-" + dead + "-00c0ffee") / "cam0_image_000000.png"); }
  // Not ours to remove: a live writer's temporary, and names that only look similar.
  { std::ofstream(dir / ("other.stl.tmp-" + live + "-11111111")) << "in progress"; }
  { std::ofstream(dir / "notes.tmp-abc") << "user file"; }
  { std::ofstream(dir / ("short.tmp-" + dead + "-123")) << "user file"; }

  ASSERT_TRUE(write_file_atomic(dir / "out.txt", "done").ok());
  EXPECT_TRUE(present(dir / "out.txt"));
  EXPECT_FALSE(present(dir / ("part.3mf.tmp-" + dead + "-0123abcd")));
  EXPECT_FALSE(present(dir / ("f_000001.png.tmp-" + dead + "-deadbeef")));
  EXPECT_FALSE(present(dir / ("cam0_image.tmp-" + dead + "-00c0ffee")));
  EXPECT_TRUE(present(dir / ("other.stl.tmp-" + live + "-11111111")));
  EXPECT_TRUE(present(dir / "notes.tmp-abc"));
  EXPECT_TRUE(present(dir / ("short.tmp-" + dead + "-123")));
  // Its own temporary is gone too, and its name carries this process's id.
  const std::string mine = temp_path_for(dir / "x.vtu").filename().string();
  EXPECT_EQ(mine.rfind("x.vtu.tmp-" + std::to_string(::getpid()) + "-", 0), 0u) << mine;
  std::size_t temporaries = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path()))
    temporaries += e.path().filename().string().find(".tmp-" + std::to_string(::getpid())) !=
                   std::string::npos;
  EXPECT_EQ(temporaries, 0u);
}

TEST(FileIo, FileGroupAppearsTogetherOrNotAtAll) {
  testing::ScratchDir dir;
  {
    // A failure after the first file: nothing under the final names, nothing staged left.
    AtomicFileGroup g(dir / "mesh", {".node", ".ele", ".vtu"});
    ASSERT_TRUE(write_file_atomic(g.staged(0), "node").ok());
  }
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) ADD_FAILURE() << e.path();

  AtomicFileGroup g(dir / "mesh", {".node", ".ele", ".vtu"});
  for (std::size_t i = 0; i < 3; ++i) ASSERT_TRUE(write_file_atomic(g.staged(i), "x").ok());
  ASSERT_TRUE(g.commit().ok());
  for (const char* ext : {".node", ".ele", ".vtu"})
    EXPECT_TRUE(present(dir / (std::string("mesh") + ext)));

  // The last rename fails (a folder is in the way): the two already renamed are taken back.
  testing::ScratchDir dir2;
  std::filesystem::create_directory(dir2 / "mesh.vtu");
  { std::ofstream(dir2 / "mesh.vtu" / "keep"); }
  AtomicFileGroup h(dir2 / "mesh", {".node", ".ele", ".vtu"});
  for (std::size_t i = 0; i < 3; ++i) ASSERT_TRUE(write_file_atomic(h.staged(i), "x").ok());
  EXPECT_FALSE(h.commit().ok());
  EXPECT_FALSE(present(dir2 / "mesh.node"));
  EXPECT_FALSE(present(dir2 / "mesh.ele"));
}

}  // namespace
}  // namespace hc
