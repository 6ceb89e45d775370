// Exact equality with dv-processing 2.0.4 on the real recordings (denoise.md §8.4, formats.md §10.3): events kept
// by BackgroundActivityNoiseFilter (2 ms, 10 ms) and KNoiseFilter (1 ms) when each file is fed whole. evpipe's
// `baf` and `knoise` must keep exactly as many. The reader delivers every event in file order (out-of-order
// events kept, as dv-processing's filters see them) and the geometry comes from the file (formats.md §10.1).
// Per-event equality with the dv-processing wheel itself: tools/check_denoise_dv.py.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe_test_data.hpp"

namespace evpipe::denoise {
namespace {

struct Golden {
  const char* file;
  std::size_t events;
  std::int64_t t_first_us, t_last_us;
  SensorGeometry geometry;
  std::size_t ba_2ms, ba_10ms, knoise_1ms;
};

// formats.md §10.1 (events, time range, size) and §10.3 / denoise.md §8.4 (kept counts).
const Golden kGolden[] = {
    {"davis346-faery/davis346.aedat4", 78'830, 1589163147368868, 1589163149728813, {346, 260}, 48'156, 73'231, 26'760},
    {"emlb-demo-01/demo-01.aedat4", 319'512, 1643243628737093, 1643243629248083, {346, 260}, 261'950, 306'204, 92'309},
    {"dvxplorer-tonic/sample.aedat4", 111'954, 1605537493718345, 1605537494308262, {320, 240}, 29'333, 72'167, 12'706},
    {"davis240c-rotdisk/IMU_rotDisk.aedat", 374'296, 341678, 3508437, {240, 180}, 147'645, 291'404, 82'916},
    {"davis240c-translboxes/IMU_translBoxes.aedat", 162'771, 294976755, 297049406, {240, 180}, 27'656, 88'063, 13'797},
};

class DvEquality : public ::testing::TestWithParam<Golden> {};

TEST_P(DvEquality, KeptCountsEqualDvProcessing) {
  const Golden& g = GetParam();
  EVPIPE_REQUIRE_REAL(path, g.file);
  io::ReaderOptions options;
  options.out_of_order = io::OutOfOrderPolicy::keep;
  auto reader = io::open_reader(path, options);
  std::vector<Event> events;
  while (auto batch = reader->next()) {
    events.insert(events.end(), batch->events.begin(), batch->events.end());
  }
  // First the input: the same events dv-processing was fed.
  ASSERT_EQ(events.size(), g.events);
  EXPECT_EQ(events.front().t_us, g.t_first_us);
  EXPECT_EQ(events.back().t_us, g.t_last_us);
  ASSERT_EQ(reader->info().geometry, g.geometry);

  struct Case {
    const char* label;
    const char* filter;
    std::vector<std::pair<std::string, std::string>> settings;
    std::size_t want;
  };
  const Case cases[] = {
      {"BA 2 ms", "baf", {}, g.ba_2ms},
      {"BA 10 ms", "baf", {{"duration_us", "10000"}}, g.ba_10ms},
      {"KNoise 1 ms", "knoise", {}, g.knoise_1ms},
  };
  for (const Case& c : cases) {
    for (const std::size_t chunk : {std::size_t{0}, std::size_t{10'000}}) {
      auto filter = make_filter(c.filter, c.settings, g.geometry);
      const Decisions d = run_filter(*filter, events, chunk);
      ASSERT_EQ(d.size(), events.size());
      EXPECT_EQ(count_kept(d), c.want) << g.file << ": " << c.label << " (pushes of " << chunk << ")";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Recordings, DvEquality, ::testing::ValuesIn(kGolden),
                         [](const ::testing::TestParamInfo<Golden>& param_info) {
                           std::string name = param_info.param.file;
                           name = name.substr(0, name.find('/'));
                           for (char& ch : name) {
                             if (ch == '-') ch = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace evpipe::denoise
