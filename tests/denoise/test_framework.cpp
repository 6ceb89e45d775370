// The filter interface, chains, parameters and the registry (filters themselves are tested in their own files).
#include <gtest/gtest.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "evpipe/denoise/chain.hpp"
#include "evpipe/denoise/filtered_stream.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {
namespace {

// Keeps every second event it sees; decides each event only when the next one arrives (one event of
// look-ahead), so the chain's bookkeeping of delayed decisions is exercised.
class EveryOtherDelayed final : public Filter {
 public:
  [[nodiscard]] std::string_view name() const noexcept override { return "every-other"; }
  void push(EventSpan events, Decisions& out) override {
    for (std::size_t i = 0; i < events.size(); ++i) {
      if (has_pending_) {
        decide(out);
      }
      has_pending_ = true;
    }
  }
  void finish(Decisions& out) override {
    if (has_pending_) {
      decide(out);
    }
  }
  void reset() override {
    has_pending_ = false;
    n_ = 0;
  }
  [[nodiscard]] std::size_t pending() const noexcept override { return has_pending_ ? 1 : 0; }

 private:
  void decide(Decisions& out) {
    out.keep.push_back((n_++ % 2 == 0) ? 1 : 0);
    has_pending_ = false;
  }
  bool has_pending_ = false;
  std::size_t n_ = 0;
};

std::vector<Event> ramp(std::size_t n) {
  std::vector<Event> ev;
  for (std::size_t i = 0; i < n; ++i) {
    ev.push_back({static_cast<std::int64_t>(i * 10), static_cast<std::uint16_t>(i % 300), 5, (i % 3) == 0});
  }
  return ev;
}

TEST(FilterChain, ComposesDelayedDecisionsInInputOrder) {
  std::vector<std::unique_ptr<Filter>> stages;
  stages.push_back(std::make_unique<EveryOtherDelayed>());
  stages.push_back(std::make_unique<EveryOtherDelayed>());
  FilterChain chain(std::move(stages));
  const auto ev = ramp(23);
  for (const std::size_t chunk : {std::size_t{0}, std::size_t{1}, std::size_t{4}}) {
    chain.reset();
    const Decisions d = run_filter(chain, ev, chunk);
    ASSERT_EQ(d.size(), ev.size()) << "chunk " << chunk;
    // Stage 1 keeps inputs 0, 2, 4, ...; stage 2 keeps every second of those: inputs 0, 4, 8, ...
    for (std::size_t i = 0; i < ev.size(); ++i) {
      EXPECT_EQ(d.keep[i], i % 4 == 0 ? 1 : 0) << "event " << i << " chunk " << chunk;
    }
    EXPECT_EQ(chain.pending(), 0U);
  }
}

TEST(FilterChain, RejectsEmpty) {
  EXPECT_THROW(FilterChain({}), std::invalid_argument);
}

EventBatchPtr labelled_batch(std::vector<Event> events, bool discontinuity = false) {
  auto b = std::make_shared<EventBatch>();
  for (const Event& e : events) {
    b->labels.push_back(e.t_us % 20 == 0 ? Label::signal : Label::noise);
  }
  b->events = std::move(events);
  b->discontinuity_before = discontinuity;
  return b;
}

TEST(FilteredStream, HandsOutKeptEventsInOrderWithTheirLabels) {
  EveryOtherDelayed f;
  std::size_t observed = 0;
  std::size_t observed_labels = 0;
  FilteredStream s(f, [&](const DecidedSegment& d) {
    observed += d.count;
    observed_labels += d.labels().size();
    EXPECT_TRUE(d.score().empty());  // the filter has no score
  });
  const auto ev = ramp(9);
  std::vector<EventBatch> out;
  s.push(labelled_batch({ev.begin(), ev.begin() + 4}), out);
  EXPECT_EQ(s.pending(), 1U);  // the last event waits for the next one
  EXPECT_EQ(observed, 3U);
  EXPECT_EQ(observed_labels, 3U);
  s.push(labelled_batch({ev.begin() + 4, ev.end()}), out);
  s.finish(out);
  EXPECT_EQ(s.pending(), 0U);
  EXPECT_EQ(observed, 9U);
  std::vector<Event> kept;
  for (const auto& b : out) {
    EXPECT_FALSE(b.discontinuity_before);
    ASSERT_EQ(b.labels.size(), b.events.size());
    for (std::size_t i = 0; i < b.size(); ++i) {
      EXPECT_EQ(b.labels[i], b.events[i].t_us % 20 == 0 ? Label::signal : Label::noise);
      kept.push_back(b.events[i]);
    }
  }
  ASSERT_EQ(kept.size(), 5U);  // inputs 0, 2, 4, 6, 8
  for (std::size_t k = 0; k < kept.size(); ++k) {
    EXPECT_EQ(kept[k], ev[2 * k]);
  }
  EXPECT_EQ(s.events_in(), 9U);
  EXPECT_EQ(s.events_decided(), 9U);
  EXPECT_EQ(s.events_kept(), 5U);
}

TEST(FilteredStream, UnlabelledInputGivesUnlabelledOutput) {
  EveryOtherDelayed f;
  FilteredStream s(f, [](const DecidedSegment& d) { EXPECT_TRUE(d.labels().empty()); });
  std::vector<EventBatch> out;
  s.push(std::make_shared<const EventBatch>(EventBatch{ramp(5), {}, false}), out);
  s.finish(out);
  ASSERT_EQ(out.size(), 2U);
  EXPECT_EQ(out[0].size() + out[1].size(), 3U);  // inputs 0, 2, 4
  EXPECT_FALSE(out[0].labelled());
  EXPECT_FALSE(out[1].labelled());
}

TEST(FilteredStream, DiscontinuityClosesTheStreamBeforeTheJump) {
  EveryOtherDelayed f;
  FilteredStream s(f);
  const auto ev = ramp(6);
  std::vector<EventBatch> out;
  s.push(labelled_batch({ev.begin(), ev.begin() + 3}), out);  // decides 0, 1; keeps 0
  ASSERT_EQ(out.size(), 1U);
  out.clear();
  s.push(labelled_batch({ev.begin() + 3, ev.end()}, true), out);
  // Event 2 (pending before the jump) is decided at the jump and kept, alone in an unflagged batch; the filter
  // restarts, so event 3 is the first of a new stream (kept) and carries the flag.
  ASSERT_EQ(out.size(), 2U);
  EXPECT_FALSE(out[0].discontinuity_before);
  ASSERT_EQ(out[0].size(), 1U);
  EXPECT_EQ(out[0].events[0], ev[2]);
  EXPECT_TRUE(out[1].discontinuity_before);
  ASSERT_EQ(out[1].size(), 1U);
  EXPECT_EQ(out[1].events[0], ev[3]);
  out.clear();
  s.finish(out);
  ASSERT_EQ(out.size(), 1U);
  EXPECT_FALSE(out[0].discontinuity_before);
  EXPECT_EQ(out[0].events[0], ev[5]);
}

// Decides a random number of its oldest pending events at each push (all of them at finish): keeps t_us % 3 == 0,
// scores t_us. Stands for any look-ahead filter, however late it decides.
class RandomDelay final : public Filter {
 public:
  explicit RandomDelay(std::uint64_t seed) : rng_(seed) {}
  [[nodiscard]] std::string_view name() const noexcept override { return "random-delay"; }
  void push(EventSpan events, Decisions& out) override {
    for (const Event& e : events) pending_.push_back(e.t_us);
    decide(static_cast<std::size_t>(rng_() % (pending_.size() + 1)), out);
  }
  void finish(Decisions& out) override { decide(pending_.size(), out); }
  void reset() override { pending_.clear(); }
  [[nodiscard]] std::size_t pending() const noexcept override { return pending_.size(); }
  [[nodiscard]] bool has_score() const noexcept override { return true; }

 private:
  void decide(std::size_t n, Decisions& out) {
    for (std::size_t i = 0; i < n; ++i) {
      out.keep.push_back(pending_.front() % 3 == 0 ? 1 : 0);
      out.score.push_back(static_cast<float>(pending_.front()));
      pending_.pop_front();
    }
  }
  std::mt19937_64 rng_;
  std::deque<std::int64_t> pending_;
};

// The bookkeeping that matches delayed decisions with their events: random batch sizes (empty ones too) and
// random delays. Every event is seen once by the observer, in input order, with its own decision, score and label.
TEST(FilteredStream, DecisionsMeetTheirEventsInInputOrder) {
  for (const std::uint64_t seed : {3U, 4U, 5U}) {
    std::mt19937_64 rng(seed);
    RandomDelay f(seed + 100);
    std::int64_t expected_t = 0;
    std::size_t at = 0;  // decisions already observed in the current call
    FilteredStream s(f, [&](const DecidedSegment& d) {
      ASSERT_EQ(d.at, at) << "seed " << seed;
      ASSERT_EQ(d.events().size(), d.count) << "seed " << seed;
      for (std::size_t i = 0; i < d.count; ++i) {
        const std::int64_t t = expected_t++;
        ASSERT_EQ(d.events()[i].t_us, t) << "seed " << seed;
        ASSERT_EQ(d.batch.events[d.first + i].t_us, t) << "seed " << seed;
        ASSERT_EQ(d.keep()[i], t % 3 == 0 ? 1 : 0) << "seed " << seed << " t " << t;
        ASSERT_EQ(d.score()[i], static_cast<float>(t)) << "seed " << seed << " t " << t;
        ASSERT_EQ(d.labels()[i], t % 20 == 0 ? Label::signal : Label::noise) << "seed " << seed << " t " << t;
      }
      at += d.count;
    });
    std::vector<EventBatch> out;
    std::int64_t next_t = 0;
    for (int round = 0; round < 500; ++round) {
      std::vector<Event> events;
      const std::size_t n = rng() % 50;
      for (std::size_t i = 0; i < n; ++i) events.push_back({next_t++, 1, 1, true});
      at = 0;
      s.push(labelled_batch(std::move(events)), out);
      ASSERT_EQ(s.pending(), f.pending()) << "seed " << seed << " round " << round;
      ASSERT_EQ(s.events_decided(), static_cast<std::uint64_t>(expected_t)) << "seed " << seed;
    }
    at = 0;
    s.finish(out);
    EXPECT_EQ(expected_t, next_t) << "seed " << seed;
    EXPECT_EQ(s.pending(), 0U) << "seed " << seed;
    // The output: exactly the kept events (t_us % 3 == 0), in order, with their labels.
    std::int64_t t = 0;
    for (const auto& b : out) {
      EXPECT_FALSE(b.discontinuity_before);
      ASSERT_EQ(b.labels.size(), b.size()) << "seed " << seed;
      for (std::size_t i = 0; i < b.size(); ++i, t += 3) {
        ASSERT_EQ(b.events[i].t_us, t) << "seed " << seed;
        ASSERT_EQ(b.labels[i], t % 20 == 0 ? Label::signal : Label::noise) << "seed " << seed;
      }
    }
    EXPECT_EQ(t, (next_t + 2) / 3 * 3) << "seed " << seed;
    EXPECT_EQ(s.events_kept(), static_cast<std::uint64_t>(t / 3)) << "seed " << seed;
  }
}

// A filter that breaks the Filter contract in one way: the stream refuses it with a message naming it.
class Faulty final : public Filter {
 public:
  enum class Fault { extra_decision, missing_score, never_decides };
  explicit Faulty(Fault fault) : fault_(fault) {}
  [[nodiscard]] std::string_view name() const noexcept override { return "faulty"; }
  void push(EventSpan events, Decisions& out) override {
    if (fault_ == Fault::never_decides) return;
    const std::size_t n = events.size() + (fault_ == Fault::extra_decision ? 1 : 0);
    out.keep.insert(out.keep.end(), n, 1);
    if (fault_ != Fault::missing_score) out.score.insert(out.score.end(), n, 0.5F);
  }
  void finish(Decisions& /*out*/) override {}
  void reset() override {}
  [[nodiscard]] bool has_score() const noexcept override { return true; }

 private:
  Fault fault_;
};

std::string error_of(Faulty::Fault fault) {
  Faulty f(fault);
  FilteredStream s(f);
  std::vector<EventBatch> out;
  try {
    s.push(labelled_batch(ramp(3)), out);
    s.finish(out);
  } catch (const std::logic_error& e) {
    return e.what();
  }
  return "no error";
}

TEST(FilteredStream, RefusesAFilterThatBreaksTheContract) {
  EXPECT_EQ(error_of(Faulty::Fault::extra_decision), "filter 'faulty' returned 4 decisions for 3 undecided events");
  EXPECT_EQ(error_of(Faulty::Fault::missing_score), "filter 'faulty' returned 0 scores for 3 decisions");
  EXPECT_EQ(error_of(Faulty::Fault::never_decides), "filter 'faulty' left 3 events undecided after finish()");
}

TEST(Params, ParsesAndValidates) {
  Params p("demo", {{"a", "2.5"}, {"n", "7"}, {"b", "off"}, {"c", "two"}});
  EXPECT_DOUBLE_EQ(p.real("a", 1.0, ""), 2.5);
  EXPECT_EQ(p.integer("n", 1, ""), 7);
  EXPECT_FALSE(p.boolean("b", true, ""));
  EXPECT_EQ(p.choice("c", "one", {"one", "two"}, ""), "two");
  EXPECT_DOUBLE_EQ(p.real("missing", 3.0, ""), 3.0);
  EXPECT_NO_THROW(p.check_all_used());
  try {
    p.require_range("a", 2.5, 0.0, 1.0, true, false);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "demo: a=2.5: must be in (0, 1]");
  }
}

TEST(Params, BadValuesAndUnknownKeysAreNamed) {
  Params p("demo", {{"a", "abc"}, {"zzz", "1"}});
  try {
    (void)p.real("a", 1.0, "");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "demo: a=abc: not a finite number");
  }
  try {
    p.check_all_used();
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown parameter 'zzz'"), std::string::npos) << e.what();
  }
  Params q("demo", {{"m", "x"}});
  EXPECT_THROW((void)q.choice("m", "a", {"a", "b"}, ""), std::invalid_argument);
  EXPECT_THROW((void)q.integer("m", 1, ""), std::invalid_argument);
}

TEST(Registry, UnknownFilterListsTheKnownOnes) {
  try {
    (void)make_filter_chain("nosuch", {}, kDavis346);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown filter 'nosuch' (known: "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("baf"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)make_filter_chain("baf,", {}, kDavis346), std::invalid_argument);
}

// Each filter of a chain holds its own per-pixel state: 40 chained copies took 3.4 GB (hostile test, session 23).
TEST(Registry, AChainHoldsAtMostkMaxChainFilters) {
  std::string chain = "baf";
  for (std::size_t i = 1; i < kMaxChainFilters; ++i) chain += ",baf";
  EXPECT_NO_THROW((void)make_filter_chain(chain, {}, kDavis346));
  try {
    (void)make_filter_chain(chain + ",baf", {}, kDavis346);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("filters, at most 8"), std::string::npos) << e.what();
  }
}

TEST(Registry, EveryFilterDescribesItsParametersAndBuildsWithDefaults) {
  for (const auto& spec : filter_specs()) {
    const auto params = describe(spec);
    for (const auto& p : params) {
      EXPECT_FALSE(p.help.empty()) << spec.name << "." << p.key;
    }
    auto f = make_filter(spec.name, {}, kDavis346);
    ASSERT_NE(f, nullptr);
    EXPECT_EQ(f->name(), spec.name);
  }
}

TEST(Registry, SettingsRouteToTheFilterThatKnowsThem) {
  auto f = make_filter_chain("baf,baf", {{"baf.duration_us", "10"}}, kDavis346);
  EXPECT_EQ(f->name(), "baf,baf");
  EXPECT_THROW((void)make_filter_chain("baf", {{"duration_us", "-5"}}, kDavis346), std::invalid_argument);
  EXPECT_THROW((void)make_filter_chain("baf", {{"nokey", "1"}}, kDavis346), std::invalid_argument);
  EXPECT_THROW((void)make_filter_chain("baf", {{"knoise.duration_us", "1"}}, kDavis346), std::invalid_argument);
}

}  // namespace
}  // namespace evpipe::denoise

namespace evpipe::denoise {
namespace {

TEST(RandomThinning, KeepsTheRequestedShareWhateverThePushes) {
  std::vector<Event> ev(200'000);
  for (std::size_t i = 0; i < ev.size(); ++i) {
    ev[i] = {static_cast<std::int64_t>(i), static_cast<std::uint16_t>(i % 346), static_cast<std::uint16_t>(i % 260),
             false};
  }
  auto f = make_filter("random", {{"keep_fraction", "0.3"}, {"seed", "7"}}, kDavis346);
  const Decisions whole = run_filter(*f, ev);
  f->reset();
  const Decisions chunked = run_filter(*f, ev, 977);
  EXPECT_EQ(whole.keep, chunked.keep);
  const double share = static_cast<double>(count_kept(whole)) / static_cast<double>(ev.size());
  EXPECT_NEAR(share, 0.3, 0.005);  // binomial sd 0.001
  auto other = make_filter("random", {{"keep_fraction", "0.3"}, {"seed", "8"}}, kDavis346);
  EXPECT_NE(run_filter(*other, ev).keep, whole.keep);
  EXPECT_THROW((void)make_filter("random", {{"keep_fraction", "1.5"}}, kDavis346), std::invalid_argument);
}

}  // namespace
}  // namespace evpipe::denoise

namespace evpipe::denoise {
namespace {

// Issue 17 row 3: a declared 65536 x 65536 sensor made baf, ynoise and stcf abort on bad_alloc and curvature spend
// minutes in its exposure model. Every filter now refuses a sensor beyond kMaxSensorSide with a message naming it,
// before allocating; at the largest accepted size every filter builds.
TEST(PixelBudget, EveryFilterRefusesASensorBeyondTheLargestAndBuildsAtIt) {
  for (const auto& spec : filter_specs()) {
    SCOPED_TRACE(std::string(spec.name));
    for (const SensorGeometry g : {SensorGeometry{65536, 65536}, SensorGeometry{kMaxSensorSide + 1, 10},
                                   SensorGeometry{10, kMaxSensorSide + 1}, SensorGeometry{0, 10}}) {
      try {
        (void)make_filter(spec.name, {}, g);
        ADD_FAILURE() << "built for " << g.width << "x" << g.height;
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("beyond the largest evpipe accepts"), std::string::npos) << e.what();
      }
    }
  }
  // The largest accepted sensor: the filters that keep per-pixel state stay within the budget.
  for (const char* name : {"baf", "ynoise", "stcf", "hotpixel", "curvature", "significance"}) {
    SCOPED_TRACE(name);
    EXPECT_NO_THROW((void)make_filter(name, {}, SensorGeometry{kMaxSensorSide, kMaxSensorSide}));
  }
}

TEST(PixelBudget, CheckNamesTheFilterAndTheBudget) {
  EXPECT_NO_THROW(check_pixel_budget("x", SensorGeometry{kMaxSensorSide, kMaxSensorSide}, kMaxFilterBytesPerPixel));
  try {
    check_pixel_budget("x", SensorGeometry{kMaxSensorSide, kMaxSensorSide}, kMaxFilterBytesPerPixel + 1);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("x: its per-pixel state for a 2048x2048 sensor would take"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace evpipe::denoise
