// evsim: writes synthetic DAVIS346 recordings with ground-truth labels (1 = signal, 0 = noise).
// Deterministic: the same arguments and seed give the same bytes.
//
//   evsim --scene demo --duration-ms 1000 --noise-hz 1 --seed 1 --out demo.aedat4 --labels demo.txt
//   evsim --pure-noise 3000 --seed 4 --out noise.txt        (the paper's section 4.1 protocol, 30 ms)
// Exit status: 0 success, 1 output error, 2 usage error.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <random>

#include "evpipe/io/writer.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/scene2d.hpp"

namespace {

void write(const std::string& path, const std::vector<evpipe::Event>& ev, const std::vector<evpipe::Label>& labels,
           evpipe::SensorGeometry geometry) {
  evpipe::io::WriterOptions o;
  o.geometry = geometry;
  o.source_name = "evsim";
  auto w = evpipe::io::open_writer(path, evpipe::io::format_for_output(path), o);
  w->write(ev, labels);
  w->close();
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_name = "demo";
  double speed = 1.0;
  double duration_ms = 1000;
  double noise_hz = 1.0;
  int hot_pixels = 0;
  double hot_rate_hz = 200;
  std::uint64_t seed = 1;
  std::size_t pure_noise = 0;
  std::int64_t t0_us = 0;
  std::string out;
  std::string labels_out;
  CLI::App app{"evsim: synthetic DAVIS346 event recordings with signal/noise labels"};
  app.add_option("--scene", scene_name, "Scene: rotating-bar, translating-rect, demo");
  app.add_option("--speed", speed, "Scene speed factor")->check(CLI::PositiveNumber);
  app.add_option("--duration-ms", duration_ms, "Length of the recording")->check(CLI::PositiveNumber);
  app.add_option("--noise-hz", noise_hz, "Background activity per pixel (Hz)")->check(CLI::NonNegativeNumber);
  app.add_option("--hot-pixels", hot_pixels, "Number of hot pixels")->check(CLI::NonNegativeNumber);
  app.add_option("--hot-rate-hz", hot_rate_hz, "Rate of each hot pixel (Hz)")->check(CLI::NonNegativeNumber);
  app.add_option("--seed", seed, "Random seed");
  app.add_option("--pure-noise", pure_noise, "Paper protocol: exactly N noise events in 30 ms, no scene");
  app.add_option("--t0-us", t0_us, "Timestamp of the start");
  app.add_option("--out", out, "Output recording (.aedat4, .aedat3 or .txt)")->required();
  app.add_option("--labels", labels_out, "Also write labelled text 't x y p label' here");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  try {
    const evpipe::SensorGeometry g = evpipe::kDavis346;
    std::mt19937_64 rng(seed);
    std::vector<evpipe::Event> signal;
    std::vector<evpipe::Event> noise;
    if (pure_noise > 0) {
      noise = evpipe::sim::uniform_noise(g, t0_us, 30'000, pure_noise, rng);
    } else {
      const auto t1_us = t0_us + static_cast<std::int64_t>(duration_ms * 1000.0);
      const auto scene = evpipe::sim::named_scene(scene_name, speed, g);
      signal = evpipe::sim::render(scene, t0_us, t1_us, {}, rng);
      evpipe::sim::NoiseOptions no;
      no.rate_hz_per_pixel = noise_hz;
      no.hot_pixels = hot_pixels;
      no.hot_rate_hz = hot_rate_hz;
      noise = evpipe::sim::background_activity(g, t0_us, t1_us, no, rng);
    }
    // Merge by time; at equal times signal first (deterministic).
    std::vector<evpipe::Event> all;
    std::vector<evpipe::Label> labels;
    all.reserve(signal.size() + noise.size());
    labels.reserve(signal.size() + noise.size());
    std::size_t i = 0, j = 0;
    while (i < signal.size() || j < noise.size()) {
      if (j >= noise.size() || (i < signal.size() && signal[i].t_us <= noise[j].t_us)) {
        all.push_back(signal[i++]);
        labels.push_back(evpipe::Label::signal);
      } else {
        all.push_back(noise[j++]);
        labels.push_back(evpipe::Label::noise);
      }
    }
    write(out, all, labels, g);
    if (!labels_out.empty()) write(labels_out, all, labels, g);
    std::printf("evsim: %zu events (%zu signal, %zu noise) -> %s\n", all.size(), signal.size(), noise.size(),
                out.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evsim: %s\n", e.what());
    return std::string(e.what()).find("unknown scene") != std::string::npos ? 2 : 1;
  }
  return 0;
}
