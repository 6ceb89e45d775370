// Format detection by content: every real recording is recognised (or rejected with a useful reason),
// and open_reader's error names the file.

#include <gtest/gtest.h>

#include <string>

#include "evpipe/io/reader.hpp"
#include "evpipe_test_data.hpp"
#include "io_test_util.hpp"

namespace evpipe::testing {
namespace {

using io::detect_format;
using io::Format;

Format detect(const Bytes& head, std::string* why = nullptr) {
  return detect_format(std::span(head.data(), std::min<std::size_t>(head.size(), 4096)), why);
}

struct RealFile {
  const char* rel;
  Format format;
};

class DetectReal : public ::testing::TestWithParam<RealFile> {};

TEST_P(DetectReal, FirstBytesGiveTheFormat) {
  EVPIPE_REQUIRE_REAL(path, GetParam().rel);
  std::string why;
  EXPECT_EQ(detect(read_bytes(path), &why), GetParam().format) << why;
}

INSTANTIATE_TEST_SUITE_P(Recordings, DetectReal,
                         ::testing::Values(RealFile{"davis240c-rotdisk/IMU_rotDisk.aedat", Format::aedat2},
                                           RealFile{"davis240c-translboxes/IMU_translBoxes.aedat", Format::aedat2},
                                           RealFile{"davis346red-aedat2-header/sample_aedat_header.aedat",
                                                    Format::aedat2},
                                           RealFile{"davis240-text-taro/test-02.txt", Format::text},
                                           RealFile{"davis346-faery/davis346.aedat4", Format::aedat4},
                                           RealFile{"davis346-faery-trimmed/sample.aedat4", Format::aedat4},
                                           RealFile{"emlb-demo-01/demo-01.aedat4", Format::aedat4},
                                           RealFile{"dvxplorer-tonic/sample.aedat4", Format::aedat4}),
                         [](const auto& param_info) {
                           std::string name = param_info.param.rel;
                           name = name.substr(0, name.find('/'));
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

struct Foreign {
  const char* rel;
  const char* why;  // expected in the reason
};

class DetectForeign : public ::testing::TestWithParam<Foreign> {};

TEST_P(DetectForeign, IsUnknownWithAReasonAndOpenReaderNamesTheFile) {
  EVPIPE_REQUIRE_REAL(path, GetParam().rel);
  std::string why;
  EXPECT_EQ(detect(read_bytes(path), &why), Format::unknown);
  EXPECT_NE(why.find(GetParam().why), std::string::npos) << why;
  try {
    io::open_reader(path);
    FAIL() << "open_reader accepted " << path;
  } catch (const FormatError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(GetParam().why), std::string::npos) << msg;
    EXPECT_EQ(e.file(), path);
  }
}

INSTANTIATE_TEST_SUITE_P(Recordings, DetectForeign,
                         ::testing::Values(Foreign{"prophesee-evt2-gen3/evt2.raw", "Prophesee RAW EVT 2.0"},
                                           Foreign{"prophesee-evt3-imx636/evt3.raw", "Prophesee RAW EVT 3.0"},
                                           Foreign{"atis-ncars-tonic/sample_ncars.dat", "Prophesee DAT"},
                                           Foreign{"atis-nmnist-tonic/sample_nmnist.bin", "binary data"}),
                         [](const auto& param_info) {
                           std::string name = param_info.param.rel;
                           name = name.substr(0, name.find('/'));
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

TEST(Detect, SyntheticHeads) {
  std::string why;
  EXPECT_EQ(detect(bytes_of("#!AER-DAT2.0\r\n# x\r\n"), &why), Format::aedat2);
  EXPECT_EQ(detect(bytes_of("#!AER-DAT3.1\r\n#Format: RAW\r\n"), &why), Format::aedat31);
  EXPECT_EQ(detect(bytes_of("#!AER-DAT4.0\r\n"), &why), Format::aedat4);
  EXPECT_EQ(detect(bytes_of("1 2 3 1\n"), &why), Format::text);
  EXPECT_EQ(detect(bytes_of("# width=346 height=260\n0.5,1,2,-1\n"), &why), Format::text);
  EXPECT_EQ(detect(bytes_of("# comments only\n"), &why), Format::text);

  EXPECT_EQ(detect({}, &why), Format::unknown);
  EXPECT_NE(why.find("empty"), std::string::npos) << why;
  EXPECT_EQ(detect(bytes_of("#!AER-DAT3.0\r\n"), &why), Format::unknown);
  EXPECT_NE(why.find("'3.0'"), std::string::npos) << why;
  Bytes aedat1 = bytes_of("# jAER 1.0 file\r\n");
  aedat1.push_back(std::byte{0x00});
  aedat1.push_back(std::byte{0x81});
  EXPECT_EQ(detect(aedat1, &why), Format::unknown);
  EXPECT_NE(why.find("AEDAT 1.0"), std::string::npos) << why;
  EXPECT_EQ(detect(bytes_of("t,x,y,p\n1,2,3,1\n"), &why), Format::unknown);
  EXPECT_NE(why.find("'t'"), std::string::npos) << why;
}

// Issue 17 row 11: an AEDAT file cut inside its version line was read as an empty text recording (a '#' comment).
TEST(Detect, CutAedatVersionLineIsNeverText) {
  std::string why;
  for (const char* head : {"#!AER", "#!AER-", "#!AER-DAT", "#!AER-DAT4", "#!AER-DAT4.", "#!AER-DA"}) {
    EXPECT_EQ(detect(bytes_of(head), &why), Format::unknown) << head;
    EXPECT_NE(why.find("cut after"), std::string::npos) << head << ": " << why;
  }
  EXPECT_EQ(detect(bytes_of("#!AER comment\n1 2 3 1\n"), &why), Format::unknown);
  EXPECT_NE(why.find("'#!AER-DAT' version line"), std::string::npos) << why;
  try {
    io::open_reader(io::memory_source(bytes_of("#!AER"), "cut.aedat4"));
    FAIL() << "a 5-byte '#!AER' file was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.aedat4: byte 0: "), std::string::npos) << e.what();
  }
  EXPECT_EQ(detect(bytes_of("#!A comment\n1 2 3 1\n"), &why), Format::text);  // an ordinary comment
}

// Issue 17: a UTF-8 byte order mark before event text was rejected as binary.
TEST(Detect, Utf8ByteOrderMarkBeforeTextIsAccepted) {
  std::string why;
  EXPECT_EQ(detect(bytes_of("\xEF\xBB\xBF# width=346 height=260\n1 2 3 1\n"), &why), Format::text) << why;
  EXPECT_EQ(detect(bytes_of("\xEF\xBB\xBF"
                            "1 2 3 1\n"),
                   &why),
            Format::text)
      << why;
  auto r = io::open_reader(io::memory_source(bytes_of("\xEF\xBB\xBF"
                                                      "1 2 3 1\n2 3 4 0\n"),
                                             "bom.txt"));
  std::size_t events = 0;
  while (auto b = r->next()) events += b->events.size();
  EXPECT_EQ(events, 2U);
}

TEST(Detect, OpenReaderRejectsUnknownAndEmptyContentNamingTheSource) {
  for (const Bytes& data : {Bytes{}, bytes_of("% evt 3.0\n"), Bytes{std::byte{0x12}, std::byte{0x00}}}) {
    try {
      io::open_reader(io::memory_source(data, "mystery.bin"));
      FAIL() << "accepted";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("mystery.bin"), std::string::npos) << e.what();
    }
  }
}

TEST(Detect, OpenReaderDispatchesByContentNotExtension) {
  auto r = io::open_reader(io::memory_source(bytes_of("#!AER-DAT2.0\r\n# AEChip: x.DAVIS240C\r\n"), "x.txt"));
  EXPECT_EQ(r->info().format, "aedat2");
  auto t = io::open_reader(io::memory_source(bytes_of("1 2 3 1\n"), "x.aedat4"));
  EXPECT_EQ(t->info().format, "text");
  auto a31 = io::open_reader(
      io::memory_source(bytes_of("#!AER-DAT3.1\r\n#Source 1: DAVIS240\r\n#!END-HEADER\r\n"), "x.aedat"));
  EXPECT_EQ(a31->info().format, "aedat3.1");
  EXPECT_EQ(a31->info().geometry, kDavis240);
  EXPECT_EQ(io::format_name(Format::aedat31), "aedat3.1");
  EXPECT_EQ(io::format_name(Format::unknown), "unknown");
}

}  // namespace
}  // namespace evpipe::testing
