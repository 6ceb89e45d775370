// evdenoise_decisions: a small helper for the Python cross-checks (tools/check_denoise_dv.py,
// tools/bench_denoise_vs_dv.py), independent of the evdenoise CLI. It reads a recording (any format evpipe reads,
// events kept in file order), runs one filter or chain through the Filter interface in pushes of --chunk events,
// and prints either one decision per event ("0" or "1", one per line, in input order), or with --count the
// line "events <n> kept <k>", or with --events the events themselves as text ("# width=W height=H", then
// "t x y p" lines: what the filters saw, for feeding the same events to another implementation), or with --bench RUNS a
// JSON line with the best throughput over RUNS passes (a fresh filter per pass, the events already in memory, the same
// chunked calling pattern as dv-processing's benchmark).
//
//   evdenoise_decisions --filter baf --set duration_us=10000 rec.aedat4 > decisions.txt
//   evdenoise_decisions --filter knoise --tile 16 --bench 5 rec.aedat4
//
// --scores prints "<decision> <score>" per event instead (the score as an exact hexadecimal float; "-" when the filter
// has none): for checking that a faster implementation decides and scores bit-identically.
// --tile N repeats the recording N times end to end (each copy shifted by the recording's span + 1 µs).
// Exit status 0, 2 on a usage error, 1 on any other error (message on stderr).

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"

namespace {

using evpipe::Event;
namespace dn = evpipe::denoise;

struct Args {
  std::string filter;
  std::vector<std::pair<std::string, std::string>> settings;
  std::size_t chunk = 10'000;
  int tile = 1;
  int bench_runs = 0;
  bool count_only = false;
  bool dump_events = false;
  bool scores = false;
  std::string file;
};

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr,
               "evdenoise_decisions: %s\nusage: evdenoise_decisions --filter NAME[,NAME...] [--set KEY=VALUE]... "
               "[--chunk N] [--tile N] [--count | --scores | --events | --bench RUNS] FILE\n",
               why.c_str());
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  auto value = [&](int& i) -> std::string {
    if (i + 1 >= argc) {
      usage(fmt::format("{} needs a value", argv[i]));
    }
    return argv[++i];
  };
  auto number = [&](int& i) -> long long {
    const std::string flag = argv[i];
    const std::string v = value(i);
    char* end = nullptr;
    const long long n = std::strtoll(v.c_str(), &end, 10);
    if (end == v.c_str() || *end != '\0' || n < 1) {
      usage(fmt::format("{} {}: expected a positive integer", flag, v));
    }
    return n;
  };
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--filter") {
      a.filter = value(i);
    } else if (arg == "--set") {
      const std::string kv = value(i);
      const auto eq = kv.find('=');
      if (eq == std::string::npos) {
        usage(fmt::format("--set {}: expected KEY=VALUE", kv));
      }
      a.settings.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    } else if (arg == "--chunk") {
      a.chunk = static_cast<std::size_t>(number(i));
    } else if (arg == "--tile") {
      a.tile = static_cast<int>(number(i));
    } else if (arg == "--bench") {
      a.bench_runs = static_cast<int>(number(i));
    } else if (arg == "--events") {
      a.dump_events = true;
    } else if (arg == "--scores") {
      a.scores = true;
    } else if (arg == "--count") {
      a.count_only = true;
    } else if (!arg.empty() && arg[0] == '-') {
      usage(fmt::format("unknown option {}", arg));
    } else if (a.file.empty()) {
      a.file = arg;
    } else {
      usage("more than one FILE");
    }
  }
  if ((a.filter.empty() && !a.dump_events) || a.file.empty()) {
    usage("--filter and FILE are required");
  }
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  try {
    evpipe::io::ReaderOptions options;
    options.out_of_order = evpipe::io::OutOfOrderPolicy::keep;  // the filters see exactly the file's events
    auto reader = evpipe::io::open_reader(args.file, options);
    std::vector<Event> events;
    while (auto batch = reader->next()) {
      events.insert(events.end(), batch->events.begin(), batch->events.end());
    }
    const evpipe::SensorGeometry geometry = reader->info().geometry;
    if (args.tile > 1 && !events.empty()) {
      const std::size_t n = events.size();
      const std::int64_t span = events.back().t_us - events.front().t_us + 1;
      events.reserve(n * static_cast<std::size_t>(args.tile));
      for (int k = 1; k < args.tile; ++k) {
        for (std::size_t i = 0; i < n; ++i) {
          Event e = events[i];
          e.t_us += span * k;
          events.push_back(e);
        }
      }
    }

    if (args.dump_events) {
      std::string out = fmt::format("# width={} height={}\n", geometry.width, geometry.height);
      for (const Event& e : events) {
        fmt::format_to(std::back_inserter(out), "{} {} {} {}\n", e.t_us, e.x, e.y, e.polarity ? 1 : 0);
      }
      std::fwrite(out.data(), 1, out.size(), stdout);
      return 0;
    }

    if (args.bench_runs > 0) {
      double best_s = 1e300;
      std::size_t kept = 0;
      for (int run = 0; run < args.bench_runs; ++run) {
        auto filter = dn::make_filter_chain(args.filter, args.settings, geometry);
        dn::Decisions d;
        d.keep.reserve(events.size());
        d.score.reserve(events.size());
        const auto t0 = std::chrono::steady_clock::now();
        for (std::size_t i = 0; i < events.size(); i += args.chunk) {
          d.clear();  // like dv-processing's fresh output store per chunk
          filter->push(evpipe::EventSpan(events).subspan(i, std::min(args.chunk, events.size() - i)), d);
          kept += dn::count_kept(d);
        }
        filter->finish(d);
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        best_s = std::min(best_s, s);
      }
      fmt::print("{{\"filter\": \"{}\", \"events\": {}, \"kept\": {}, \"best_s\": {:.6f}, \"mev_s\": {:.3f}}}\n",
                 args.filter, events.size(), kept / static_cast<std::size_t>(args.bench_runs), best_s,
                 static_cast<double>(events.size()) / best_s * 1e-6);
      return 0;
    }

    auto filter = dn::make_filter_chain(args.filter, args.settings, geometry);
    const dn::Decisions d = dn::run_filter(*filter, events, args.chunk);
    if (args.count_only) {
      fmt::print("events {} kept {}\n", events.size(), dn::count_kept(d));
      return 0;
    }
    std::string out;
    if (args.scores) {
      for (std::size_t i = 0; i < d.keep.size(); ++i) {
        if (d.score.size() == d.keep.size()) {
          fmt::format_to(std::back_inserter(out), "{} {:a}\n", d.keep[i] != 0 ? 1 : 0, d.score[i]);
        } else {
          fmt::format_to(std::back_inserter(out), "{} -\n", d.keep[i] != 0 ? 1 : 0);
        }
      }
      std::fwrite(out.data(), 1, out.size(), stdout);
      return 0;
    }
    out.reserve(d.keep.size() * 2);
    for (const auto k : d.keep) {
      out += k != 0 ? "1\n" : "0\n";
    }
    std::fwrite(out.data(), 1, out.size(), stdout);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evdenoise_decisions: %s\n", e.what());
    return 1;
  }
}
