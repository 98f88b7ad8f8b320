// What ddhgs may replace: only folders it wrote and marked, never a folder
// that is or holds the current directory, the home folder, a mount point or
// an input. Every test works inside its own temporary folder; the roots,
// homes and mount points are stand-ins given through io::PathContext.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"
#include "io/files/output_marker.h"
#include "io/files/stale_files.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

std::string error_of(const std::function<void()>& action) {
  try {
    action();
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A build that writes one file.
std::function<void(const fs::path&)> writes(const std::string& name, const std::string& text) {
  return [=](const fs::path& tmp) { write_file_atomically(tmp / name, text); };
}

// A process id that is certainly not running: a child that has exited.
long dead_pid() {
  pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return long(child);
}

TEST(OutputFolder, NeverReplacesAFolderItDidNotWrite) {
  const fs::path dir = test::temp_dir("output_foreign");
  fs::create_directories(dir / "mine");
  write_file_atomically(dir / "mine" / "thesis.tex", "years of work");
  for (bool replace : {false, true}) {
    const std::string e = error_of([&] {
      write_folder_atomically({dir / "mine", OutputKind::Scene, replace, {}}, writes("a", "b"));
    });
    EXPECT_TRUE(contains(e, "holds files ddhgs did not write")) << e;
    EXPECT_TRUE(contains(e, "nothing was touched")) << e;
    EXPECT_EQ(read_file(dir / "mine" / "thesis.tex"), "years of work");
  }
  // A file where the folder should be is not replaced either.
  write_file_atomically(dir / "file", "data");
  EXPECT_TRUE(contains(
      error_of([&] {
        write_folder_atomically({dir / "file", OutputKind::Scene, true, {}}, writes("a", "b"));
      }),
      "exists and is not a folder"));
  EXPECT_EQ(read_file(dir / "file"), "data");
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"file", "mine"}));
}

TEST(OutputFolder, ReplacesItsOwnOutputOfTheSameKindOnlyWhenAsked) {
  const fs::path dir = test::temp_dir("output_own");
  const fs::path out = dir / "scene";
  write_folder_atomically({out, OutputKind::Scene, false, {}}, writes("a.txt", "first"));
  EXPECT_EQ(output_kind(out), OutputKind::Scene);
  EXPECT_TRUE(contains(
      error_of([&] {
        write_folder_atomically({out, OutputKind::Scene, false, {}}, writes("a.txt", "second"));
      }),
      "pass --force to replace it"));
  EXPECT_TRUE(contains(
      error_of([&] {
        write_folder_atomically({out, OutputKind::Run, true, {}}, writes("a.txt", "second"));
      }),
      "is a ddhgs scene, not a run"));
  EXPECT_EQ(read_file(out / "a.txt"), "first");
  write_folder_atomically({out, OutputKind::Scene, true, {}}, writes("b.txt", "second"));
  EXPECT_EQ(listing(out), (std::vector<std::string>{".ddhgs-output", "b.txt"}));
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"scene"}));  // no temporaries left
}

TEST(OutputFolder, FailedBuildLeavesTheEarlierOutputAsItWas) {
  const fs::path dir = test::temp_dir("output_failed_build");
  const fs::path out = dir / "report";
  write_folder_atomically({out, OutputKind::Report, true, {}}, writes("index.html", "old"));
  EXPECT_THROW(write_folder_atomically({out, OutputKind::Report, true, {}},
                                       [](const fs::path& tmp) {
                                         write_file_atomically(tmp / "index.html", "half");
                                         throw core::Error("disk full");
                                       }),
               core::Error);
  EXPECT_EQ(read_file(out / "index.html"), "old");
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"report"}));
}

TEST(OutputFolder, NeverTouchesInputsOrFoldersHoldingThem) {
  const fs::path dir = test::temp_dir("output_inputs");
  write_folder_atomically({dir / "data", OutputKind::Scene, false, {}}, writes("cube.npy", "x"));
  // The input itself, a folder holding it, and the same folder spelled otherwise.
  for (const fs::path& out : {dir / "data", dir, dir / "data" / ".." / "data" / ""}) {
    const std::string e = error_of([&] {
      write_folder_atomically({out, OutputKind::Scene, true, {dir / "data"}}, writes("a", "b"));
    });
    EXPECT_TRUE(contains(e, "input")) << out << ": " << e;
  }
  fs::create_symlink(dir / "data", dir / "link");
  EXPECT_TRUE(contains(
      error_of([&] {
        write_folder_atomically({dir / "out", OutputKind::Scene, true, {dir / "link" / "cube.npy"}},
                                writes("a", "b"));
        write_folder_atomically(
            {dir / "data", OutputKind::Scene, true, {dir / "link" / "cube.npy"}}, writes("a", "b"));
      }),
      "contains this command's input"));
  EXPECT_EQ(read_file(dir / "data" / "cube.npy"), "x");
  // A symbolic link is not replaced: the folder it points to would be.
  EXPECT_TRUE(contains(
      error_of([&] {
        write_folder_atomically({dir / "link", OutputKind::Scene, true, {}}, writes("a", "b"));
      }),
      "symbolic link"));
  EXPECT_EQ(read_file(dir / "data" / "cube.npy"), "x");
}

TEST(OutputFolder, NeverTouchesTheCurrentDirectoryHomeOrAMountPoint) {
  const fs::path dir = test::temp_dir("output_protected");
  for (const char* name : {"cwd", "home", "mnt"})
    write_folder_atomically({dir / name, OutputKind::Scene, false, {}}, writes("a", "b"));
  PathContext context;
  context.cwd = dir / "cwd";
  context.home = dir / "home";
  context.is_mount_point = [&](const fs::path& p) { return p == dir / "mnt"; };
  auto reason = [&](const fs::path& p) { return protected_reason(p, {}, context); };
  EXPECT_EQ(reason(dir / "cwd"), "is the current directory");
  EXPECT_EQ(reason(dir / "home"), "is your home folder");
  EXPECT_EQ(reason(dir / "mnt"), "is a mount point");
  EXPECT_EQ(reason(dir), "contains the current directory");
  EXPECT_EQ(reason(dir / "other"), "");
  for (const char* name : {"cwd", "home", "mnt"}) {
    const std::string e = error_of([&] {
      check_output_folder({dir / name, OutputKind::Scene, true, {}}, context);
    });
    EXPECT_TRUE(contains(e, "nothing was touched")) << e;
    EXPECT_EQ(read_file(dir / name / "a"), "b");
  }
  // The real surroundings: this test's temporary folder is none of them.
  EXPECT_EQ(protected_reason(dir / "cwd", {}), "");
}

TEST(OutputFolder, WriteIntoRemovesWhatTheNewFilesSupersede) {
  const fs::path dir = test::temp_dir("output_superseded");
  const fs::path out = dir / "renders";
  OutputRequest request{out, OutputKind::Renders, true, {}, ""};
  write_into_folder_atomically(request, [](const fs::path& tmp) {
    write_file_atomically(tmp / "v1.npy", "cube");
    write_file_atomically(tmp / "v2.npy", "cube");
    write_file_atomically(tmp / "v1_rgb.png", "rgb");
  });
  write_file_atomically(out / "notes.npy", "the user's");  // not ddhgs's
  // An ENVI render of v1 makes its .npy stale; v2 (not rendered now), the
  // picture and the user's file stay, and a name both superseded and
  // written again is kept.
  request.superseded = {"v1.npy", "notes.npy", "v1.hdr", "absent.npy"};
  write_into_folder_atomically(request, [](const fs::path& tmp) {
    write_file_atomically(tmp / "v1.hdr", "header");
    write_file_atomically(tmp / "v1.img", "samples");
  });
  EXPECT_EQ(listing(out), (std::vector<std::string>{".ddhgs-output", "notes.npy", "v1.hdr",
                                                    "v1.img", "v1_rgb.png", "v2.npy"}));
  // The marker no longer lists the removed file: only notes.npy is foreign.
  EXPECT_EQ(foreign_entries(out, *read_output_marker(out)),
            (std::vector<std::string>{"notes.npy"}));
}

TEST(OutputFolder, WriteIntoAddsFilesAndKeepsTheOthers) {
  const fs::path dir = test::temp_dir("output_into");
  const fs::path out = dir / "renders";
  const OutputRequest request{out, OutputKind::Renders, true, {}, ""};
  write_into_folder_atomically(request, writes("v1_rgb.png", "rgb"));
  write_into_folder_atomically(request, writes("v1_band3.png", "band"));
  write_into_folder_atomically(request, writes("v1_rgb.png", "rgb again"));
  EXPECT_EQ(listing(out),
            (std::vector<std::string>{".ddhgs-output", "v1_band3.png", "v1_rgb.png"}));
  EXPECT_EQ(read_file(out / "v1_rgb.png"), "rgb again");
  // A failed build adds nothing.
  EXPECT_THROW(write_into_folder_atomically(request,
                                            [](const fs::path& tmp) {
                                              write_file_atomically(tmp / "v2_rgb.png", "x");
                                              throw core::Error("out of memory");
                                            }),
               core::Error);
  EXPECT_EQ(listing(out),
            (std::vector<std::string>{".ddhgs-output", "v1_band3.png", "v1_rgb.png"}));
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"renders"}));
  // Not into a folder of another kind or one ddhgs did not write.
  fs::create_directories(dir / "photos");
  write_file_atomically(dir / "photos" / "holiday.png", "sun");
  EXPECT_TRUE(contains(error_of([&] {
                         write_into_folder_atomically(
                             {dir / "photos", OutputKind::Renders, true, {}},
                             writes("v1_rgb.png", "x"));
                       }),
                       "did not write"));
  EXPECT_EQ(listing(dir / "photos"), (std::vector<std::string>{"holiday.png"}));
}

// A run written in place, declaring the one file it writes.
OutputRequest run_request(const fs::path& out) {
  OutputRequest request{out, OutputKind::Run, true, {}};
  request.entries = {"gaussians.ply"};
  return request;
}

TEST(OutputFolder, ReplacementKeepsTheEarlierOutputAsideUntilCommitted) {
  const fs::path dir = test::temp_dir("output_replacement");
  const fs::path out = dir / "run";
  write_folder_atomically({out, OutputKind::Run, false, {}}, writes("gaussians.ply", "good"));
  FolderReplacement first(run_request(out));
  first.begin();
  EXPECT_EQ(first.aside(), dir / "run.previous");
  EXPECT_EQ(read_file(dir / "run.previous" / "gaussians.ply"), "good");
  first.rollback();
  EXPECT_EQ(read_file(out / "gaussians.ply"), "good");
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"run"}));

  FolderReplacement second(run_request(out));
  second.begin();
  write_file_atomically(out / "gaussians.ply", "better");
  // Interrupted here. Another replacement refuses while run.previous waits.
  FolderReplacement third(run_request(out));
  EXPECT_TRUE(contains(error_of([&] { third.begin(); }), "did not finish"));
  EXPECT_EQ(read_file(dir / "run.previous" / "gaussians.ply"), "good");
  // Continued later: the pending replacement is found again and completed.
  FolderReplacement continued(run_request(out));
  continued.resume();
  EXPECT_TRUE(continued.replacing());
  continued.commit();
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"run"}));
  EXPECT_EQ(read_file(out / "gaussians.ply"), "better");
  FolderReplacement again(run_request(out));
  again.resume();
  EXPECT_FALSE(again.replacing());
}

// --force replaces only what ddhgs wrote: anything else in the folder, or in
// an output nested in it, is named and the folder left as it was.
TEST(OutputFolder, ReplacingRefusesWhileTheOutputHoldsAUsersFiles) {
  const fs::path dir = test::temp_dir("output_foreign");
  const fs::path out = dir / "run";
  {
    FolderReplacement run(run_request(out));
    run.begin();
    write_file_atomically(out / "gaussians.ply", "model");
    run.commit();
  }
  write_folder_atomically({out / "report", OutputKind::Report, false, {}},
                          writes("index.html", "page"));
  // Nothing but ddhgs's: replaced.
  EXPECT_EQ(check_output_folder(run_request(out)), OutputState::Ours);
  write_file_atomically(out / "notes.txt", "my notes");
  write_file_atomically(out / "report" / "annotations.md", "mine too");
  const std::string e = error_of([&] { FolderReplacement(run_request(out)).begin(); });
  EXPECT_TRUE(contains(e, "holds files ddhgs did not write (notes.txt, report/annotations.md)"))
      << e;
  EXPECT_TRUE(contains(e, "nothing was touched")) << e;
  EXPECT_EQ(read_file(out / "notes.txt"), "my notes");
  EXPECT_EQ(listing(dir), (std::vector<std::string>{"run"}));
  // The report alone is refused too; adding files to it is not.
  const std::string r = error_of([&] {
    write_folder_atomically({out / "report", OutputKind::Report, true, {}}, writes("a", "b"));
  });
  EXPECT_TRUE(contains(r, "annotations.md")) << r;
  write_into_folder_atomically({out / "report", OutputKind::Report, true, {}},
                               writes("extra.html", "more"));
  EXPECT_EQ(read_file(out / "report" / "annotations.md"), "mine too");
  // and what was added is ddhgs's from then on.
  fs::remove(out / "report" / "annotations.md");
  fs::remove(out / "notes.txt");
  EXPECT_EQ(check_output_folder(run_request(out)), OutputState::Ours);
}

// A marker copied or linked into a user's folder does not make it ddhgs's.
TEST(OutputFolder, ACopiedOrLinkedMarkerIsNoLicence) {
  const fs::path dir = test::temp_dir("output_fake_marker");
  write_folder_atomically({dir / "report", OutputKind::Report, false, {}},
                          writes("index.html", "page"));
  const fs::path mine = dir / "mine";
  fs::create_directories(mine);
  write_file_atomically(mine / "thesis.tex", "years of work");
  fs::copy_file(dir / "report" / kOutputMarker, mine / kOutputMarker);
  const auto replace_mine = [&] {
    write_folder_atomically({mine, OutputKind::Report, true, {}}, writes("index.html", "x"));
  };
  EXPECT_TRUE(contains(error_of(replace_mine), "thesis.tex"));
  fs::remove(mine / kOutputMarker);
  fs::create_symlink(dir / "report" / kOutputMarker, mine / kOutputMarker);
  EXPECT_TRUE(contains(error_of(replace_mine), "did not write")) << error_of(replace_mine);
  // A marker of an older ddhgs (no list of files): it cannot tell, so it refuses.
  fs::remove(mine / kOutputMarker);
  write_file_atomically(mine / kOutputMarker, "ddhgs report\n");
  EXPECT_TRUE(contains(error_of(replace_mine), "older ddhgs")) << error_of(replace_mine);
  EXPECT_EQ(read_file(mine / "thesis.tex"), "years of work");
}

TEST(OutputFolder, StaleTemporariesAreRemovedOnlyWhereTheyAreProvablyOurs) {
  const fs::path dir = test::temp_dir("output_stale");
  const std::string dead = std::to_string(dead_pid());
  const std::string alive = std::to_string(::getppid());
  // Beside outputs, in a folder ddhgs did not write: a name proves nothing.
  write_file_atomically(dir / (".ckpt.pt.tmp-" + dead + "-0"), "5 MB");
  write_file_atomically(dir / (".notes.tmp-999999-1"), "a user's notes");
  write_file_atomically(dir / (".ckpt.pt.tmp-" + alive + "-0"), "being written");
  fs::create_directories(dir / (".scene.tmp-" + dead));
  mark_output_folder(dir / (".scene.tmp-" + dead), OutputKind::Scene);  // marker only: ours
  fs::create_directories(dir / (".empty.tmp-" + dead));
  fs::create_directories(dir / (".report.tmp-" + dead));  // a marker and results: may be a copy
  mark_output_folder(dir / (".report.tmp-" + dead), OutputKind::Report);
  write_file_atomically(dir / (".report.tmp-" + dead) / "index.html", "x");
  fs::create_directories(dir / (".photos.tmp-" + dead));
  write_file_atomically(dir / (".photos.tmp-" + dead) / "a.jpg", "x");
  write_file_atomically(dir / (".notes.tmp-" + dead), "a file named like a folder's temporary");
  write_file_atomically(dir / "keep.txt", "user file");
  // Stale files are removed by the next write into the same folder (a fresh
  // process scans each folder once; this test calls the scan directly).
  remove_stale_temporaries(dir);
  // listing() is sorted by name; the pids decide where the two .ckpt names fall.
  std::vector<std::string> left{".ckpt.pt.tmp-" + alive + "-0",
                                ".ckpt.pt.tmp-" + dead + "-0",
                                ".notes.tmp-" + dead,
                                ".notes.tmp-999999-1",
                                ".photos.tmp-" + dead,
                                ".report.tmp-" + dead,
                                "keep.txt"};
  std::sort(left.begin(), left.end());
  EXPECT_EQ(listing(dir), left);
  // Inside an output of ddhgs's own, its file temporaries go.
  const fs::path run = dir / "run";
  fs::create_directories(run);
  mark_output_folder(run, OutputKind::Run);
  write_file_atomically(run / (".checkpoint.pt.tmp-" + dead + "-3"), "half a checkpoint");
  write_file_atomically(run / (".checkpoint.pt.tmp-" + alive + "-3"), "being written");
  remove_stale_temporaries(run);
  EXPECT_EQ(listing(run),
            (std::vector<std::string>{".checkpoint.pt.tmp-" + alive + "-3", ".ddhgs-output"}));
  EXPECT_EQ(parse_temporary_name(".a.tmp-12-3")->owner, 12);
  EXPECT_TRUE(parse_temporary_name(".a.tmp-12-3")->is_file);
  EXPECT_FALSE(parse_temporary_name(".a.old-12")->is_file);
  EXPECT_FALSE(parse_temporary_name("a.tmp-12-3"));
  EXPECT_FALSE(parse_temporary_name(".a.tmp-x"));
}

TEST(OutputFolder, LockRefusesASecondWriterAndNamesTheFirst) {
  const fs::path dir = test::temp_dir("output_lock");
  {
    FolderLock first(dir, "train");
    const std::string e = error_of([&] { FolderLock second(dir, "eval"); });
    EXPECT_TRUE(contains(e, "in use by ddhgs train (pid " + std::to_string(::getpid()) + ")")) << e;
  }
  EXPECT_NO_THROW(FolderLock(dir, "eval"));  // released with its owner
}

// A lock file linked to someone else's file: refused, the file untouched.
TEST(OutputFolder, LockNeverFollowsALink) {
  const fs::path dir = test::temp_dir("output_lock_link");
  const fs::path run = dir / "run", victim = dir / "victim.txt";
  fs::create_directories(run);
  write_file_atomically(victim, "another user's file\n");
  fs::create_symlink(victim, run / kLockFile);
  const std::string e = error_of([&] { FolderLock lock(run, "eval"); });
  EXPECT_TRUE(contains(e, "is a symbolic link")) << e;
  EXPECT_TRUE(contains(e, (run / kLockFile).string())) << e;
  EXPECT_EQ(read_file(victim), "another user's file\n");
  fs::remove(run / kLockFile);
  fs::create_directory(run / kLockFile);  // not a file at all
  EXPECT_TRUE(contains(error_of([&] { FolderLock lock(run, "eval"); }), "not a regular file"));
}

}  // namespace
}  // namespace ddhgs::io
