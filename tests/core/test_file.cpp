// evpipe/core/file.hpp: regular inputs only (a FIFO without a writer must not block), size caps, and "an output is
// never an input" (issue 17 rows 4, 5, 7, 9).

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "evpipe/core/file.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;

namespace {

class FileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("evpipe_file_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name), std::ios::binary) << text;
    return path(name);
  }
  static std::string slurp(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  fs::path dir_;
};

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const evpipe::FileError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_F(FileTest, InputFifoWithoutWriterIsRefusedWithoutBlocking) {
  const std::string fifo = path("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { (void)evpipe::open_input_file(fifo); }), fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(error_of([&] { (void)evpipe::read_small_file(fifo, 100); }), fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(error_of([&] { evpipe::check_input_file(fifo); }), fifo + ": is a FIFO, not a regular file");
}

TEST_F(FileTest, InputDirectoryDeviceAndMissingFile) {
  EXPECT_EQ(error_of([&] { (void)evpipe::open_input_file(dir_.string()); }),
            dir_.string() + ": is a directory, not a regular file");
  EXPECT_EQ(error_of([&] { (void)evpipe::open_input_file("/dev/zero"); }),
            "/dev/zero: is a character device, not a regular file");
  EXPECT_THAT(error_of([&] { (void)evpipe::open_input_file(path("missing")); }), HasSubstr("missing: cannot open: "));
}

TEST_F(FileTest, ReadSmallFileCapsTheSize) {
  const std::string p = write("a.yaml", std::string(100, 'x'));
  EXPECT_EQ(evpipe::read_small_file(p, 100).size(), 100U);
  EXPECT_EQ(error_of([&] { (void)evpipe::read_small_file(p, 99, "a configuration"); }),
            p + ": file is 100 bytes, more than the 99 accepted for a configuration");
  EXPECT_EQ(evpipe::read_small_file(write("empty", ""), 10), "");
}

TEST_F(FileTest, OutputThatIsAnInputIsRefusedBeforeTruncating) {
  const std::string in = write("in.txt", "precious");
  const std::vector<std::string> inputs = {"", in};
  EXPECT_EQ(error_of([&] { (void)evpipe::open_output_file(in, inputs); }),
            in + ": is also an input of this program: refusing to overwrite it");
  // A hard link and a symbolic link of the input are the same file.
  fs::create_hard_link(in, path("hard.txt"));
  fs::create_symlink(in, path("soft.txt"));
  EXPECT_EQ(error_of([&] { (void)evpipe::open_output_file(path("hard.txt"), inputs); }),
            path("hard.txt") + ": is the same file as the input " + in + ": refusing to overwrite it");
  EXPECT_THAT(error_of([&] { (void)evpipe::open_output_file(path("soft.txt"), inputs); }),
              HasSubstr("is the same file as the input"));
  EXPECT_THAT(error_of([&] { evpipe::check_output_file(path("hard.txt"), inputs); }),
              HasSubstr("is the same file as the input"));
  EXPECT_EQ(slurp(in), "precious");
}

TEST_F(FileTest, OutputIsCreatedOrTruncated) {
  const std::string in = write("in.txt", "x");
  const std::string out = write("out.txt", "old contents");
  const std::vector<std::string> inputs = {in};
  {
    auto f = evpipe::open_output_file(out, inputs);
    std::fputs("new", f.get());
  }
  EXPECT_EQ(slurp(out), "new");
  { auto f = evpipe::open_output_file(path("fresh.txt"), inputs); }
  EXPECT_TRUE(fs::exists(path("fresh.txt")));
  evpipe::check_output_file(path("not-yet.txt"), inputs);  // fine: does not exist
}

TEST_F(FileTest, OutputKinds) {
  EXPECT_EQ(error_of([&] { (void)evpipe::open_output_file(dir_.string()); }),
            dir_.string() + ": is a directory, not a file to write");
  { auto f = evpipe::open_output_file("/dev/null"); }  // a character device is a documented exception
  const std::string fifo = path("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { (void)evpipe::open_output_file(fifo); }),
            fifo + ": is a FIFO that no process reads: cannot write to it");
  EXPECT_THAT(error_of([&] { (void)evpipe::open_output_file(path("no/such/dir/x.txt")); }),
              HasSubstr("cannot create: No such file or directory"));
}
