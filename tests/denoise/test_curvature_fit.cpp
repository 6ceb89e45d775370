// The curvature filter's building blocks: the sphere's site table, the exact singular-fit test, the quadric
// fit (against Eigen's QR on the explicit design matrix), the selection rules and the noise-rate model.
#include <gtest/gtest.h>

// GCC 12 reports a false -Wmaybe-uninitialized inside Eigen's AVX-512 kernels (native builds); the pragma
// covers the header's code only (clang has no such warning).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <Eigen/Dense>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#include <cmath>
#include <random>
#include <stdexcept>

#include "evpipe/denoise/noise_rate.hpp"
#include "evpipe/denoise/quadric.hpp"
#include "evpipe/denoise/selection.hpp"
#include "evpipe/denoise/sphere.hpp"

namespace evpipe::denoise {
namespace {

std::int64_t half_width(const Sphere& s, int dx, int dy) {
  const int i = s.site_index(dx, dy);
  return i < 0 ? -1 : s.sites()[static_cast<std::size_t>(i)].half_width_us;
}

TEST(Sphere, PaperParametersInclusiveHave13Sites) {
  const Sphere s(2.0, 10'000, true);
  EXPECT_EQ(s.size(), 13);
  EXPECT_EQ(s.pairs(), 6);
  EXPECT_EQ(s.extent_px(), 2);
  EXPECT_EQ(s.limit(), 400'000'000);
  EXPECT_EQ(s.reach_us(), 20'000);
  EXPECT_EQ(s.sites()[0].dx, 0);
  EXPECT_EQ(s.sites()[0].dy, 0);
  for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) EXPECT_EQ(half_width(s, dx, dy), 17'320);
  for (const auto& [dx, dy] : {std::pair{1, 1}, {-1, 1}, {1, -1}, {-1, -1}}) EXPECT_EQ(half_width(s, dx, dy), 14'142);
  for (const auto& [dx, dy] : {std::pair{2, 0}, {-2, 0}, {0, 2}, {0, -2}}) EXPECT_EQ(half_width(s, dx, dy), 0);
  EXPECT_EQ(s.site_index(2, 1), -1);
  EXPECT_EQ(s.site_index(3, 0), -1);
  // Pairs are antipodal.
  for (int p = 0; p < s.pairs(); ++p) {
    const auto& a = s.sites()[static_cast<std::size_t>(1 + 2 * p)];
    const auto& b = s.sites()[static_cast<std::size_t>(2 + 2 * p)];
    EXPECT_EQ(a.dx, -b.dx);
    EXPECT_EQ(a.dy, -b.dy);
    EXPECT_EQ(a.half_width_us, b.half_width_us);
  }
  // Exact boundary: 17320² + 10⁸ ≤ 4·10⁸ < 17321² + 10⁸.
  EXPECT_TRUE(s.contains(1, 0, 17'320));
  EXPECT_FALSE(s.contains(1, 0, 17'321));
  EXPECT_TRUE(s.contains(-1, -1, -14'142));
  EXPECT_FALSE(s.contains(-1, -1, -14'143));
  EXPECT_TRUE(s.contains(0, 0, -20'000));
  EXPECT_FALSE(s.contains(0, 0, 20'001));
  EXPECT_TRUE(s.contains(0, -2, 0));
  EXPECT_FALSE(s.contains(0, -2, 1));
}

TEST(Sphere, PaperParametersStrictHave9Sites) {
  const Sphere s(2.0, 10'000, false);
  EXPECT_EQ(s.size(), 9);
  EXPECT_EQ(s.limit(), 399'999'999);
  EXPECT_EQ(s.reach_us(), 19'999);
  EXPECT_EQ(half_width(s, 1, 0), 17'320);
  EXPECT_EQ(half_width(s, 1, 1), 14'142);
  EXPECT_EQ(s.site_index(2, 0), -1);
}

TEST(Sphere, SiteCountsAndLimits) {
  EXPECT_EQ(Sphere(1.0, 100, true).size(), 5);   // centre + 4 at Δt = 0
  EXPECT_EQ(Sphere(1.0, 100, false).size(), 1);  // centre only
  EXPECT_EQ(Sphere(1.5, 10'000, true).size(), 9);
  EXPECT_EQ(Sphere(4.0, 10'000, true).size(), 49);
  EXPECT_EQ(Sphere(4.0, 10'000, true).extent_px(), 4);
  EXPECT_EQ(Sphere(2.5, 10'000, true).limit(), 625'000'000);
  EXPECT_THROW(Sphere(0.0, 10'000, true), std::invalid_argument);
  EXPECT_THROW(Sphere(-2.0, 10'000, true), std::invalid_argument);
  EXPECT_THROW(Sphere(4.01, 10'000, true), std::invalid_argument);
  EXPECT_THROW(Sphere(2.0, 0, true), std::invalid_argument);
  EXPECT_THROW(Sphere(std::nan(""), 10'000, true), std::invalid_argument);
}

TEST(Sphere, ExhaustiveMembershipMatchesTheIntegerTest) {
  for (const bool inclusive : {true, false}) {
    for (const double r : {1.0, 1.5, 2.0, 2.3, 3.0}) {
      const std::int64_t lt = 97;
      const Sphere s(r, lt, inclusive);
      const long double r2 = static_cast<long double>(r) * r * lt * lt;
      for (int dy = -4; dy <= 4; ++dy) {
        for (int dx = -4; dx <= 4; ++dx) {
          for (std::int64_t dt = -400; dt <= 400; ++dt) {
            const auto d2 = static_cast<long double>((dx * dx + dy * dy) * lt * lt + dt * dt);
            const bool in = inclusive ? d2 <= r2 : d2 < r2;
            ASSERT_EQ(s.contains(dx, dy, dt), in)
                << "r=" << r << " inclusive=" << inclusive << " dx=" << dx << " dy=" << dy << " dt=" << dt;
          }
        }
      }
    }
  }
}

std::uint64_t mask_of(const Sphere& s, std::initializer_list<std::pair<int, int>> sites) {
  std::uint64_t m = 0;
  for (const auto& [dx, dy] : sites) {
    const int i = s.site_index(dx, dy);
    EXPECT_GE(i, 0);
    m |= std::uint64_t{1} << i;
  }
  return m;
}

TEST(Quadric, DesignRankOfTheSingularConfigurations) {
  using P = std::pair<int, int>;
  const std::vector<P> one = {{0, 0}};
  const std::vector<P> line = {{-2, 0}, {-1, 0}, {0, 0}, {1, 0}, {2, 0}};
  const std::vector<P> cross = {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  const std::vector<P> parallel = {{-1, -1}, {-1, 0}, {-1, 1}, {1, -1}, {1, 0}, {1, 1}};
  const std::vector<P> diagonals = {{0, 0}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}};
  const std::vector<P> square = {{-1, -1}, {0, -1}, {1, -1}, {-1, 0}, {0, 0}, {1, 0}, {-1, 1}, {0, 1}, {1, 1}};
  EXPECT_EQ(quadric_design_rank(one), 1);
  EXPECT_EQ(quadric_design_rank(line), 3);
  EXPECT_EQ(quadric_design_rank(cross), 5);
  EXPECT_EQ(quadric_design_rank(parallel), 5);
  EXPECT_EQ(quadric_design_rank(diagonals), 5);
  EXPECT_EQ(quadric_design_rank(square), 6);

  const Sphere s(2.0, 10'000, true);
  SingularMaskTable table(s);
  EXPECT_FALSE(table.full_rank(mask_of(s, {{0, 0}})));
  EXPECT_FALSE(table.full_rank(mask_of(s, {{-2, 0}, {-1, 0}, {0, 0}, {1, 0}, {2, 0}})));
  EXPECT_FALSE(table.full_rank(mask_of(s, {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}})));
  EXPECT_FALSE(table.full_rank(mask_of(s, {{-1, -1}, {-1, 0}, {-1, 1}, {1, -1}, {1, 0}, {1, 1}})));
  EXPECT_TRUE(table.full_rank(mask_of(s, {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}})));
  // The cross plus the four far sites is still u·v = 0.
  EXPECT_FALSE(
      table.full_rank(mask_of(s, {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}, {2, 0}, {-2, 0}, {0, 2}, {0, -2}})));
}

TEST(Quadric, MaskTableAgreesWithEigenRankOnEveryMask) {
  // All 2¹³ masks of the paper's sphere against a floating-point rank of the explicit design matrix.
  const Sphere s(2.0, 10'000, true);
  SingularMaskTable table(s);
  for (std::uint64_t mask = 0; mask < (std::uint64_t{1} << s.size()); ++mask) {
    Eigen::MatrixXd x(std::max(1, __builtin_popcountll(mask)), 6);
    x.setZero();
    int r = 0;
    for (int i = 0; i < s.size(); ++i) {
      if (((mask >> i) & 1U) == 0) continue;
      const double u = s.sites()[static_cast<std::size_t>(i)].dx;
      const double v = s.sites()[static_cast<std::size_t>(i)].dy;
      x.row(r++) << 1, u, v, u * u, v * v, u * v;
    }
    Eigen::FullPivLU<Eigen::MatrixXd> lu(x);
    lu.setThreshold(1e-9);
    ASSERT_EQ(table.full_rank(mask), lu.rank() == 6) << "mask " << mask;
  }
}

TEST(Quadric, FitMatchesEigenQrOnTheExplicitDesignMatrix) {
  const std::uint64_t seed = 20250704;
  std::mt19937_64 rng(seed);
  const Sphere s(2.0, 10'000, true);
  std::uniform_int_distribution<int> count(0, 3);
  int fitted = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::vector<std::int32_t> counts(static_cast<std::size_t>(s.size()));
    std::vector<std::int64_t> sums(static_cast<std::size_t>(s.size()));
    std::vector<std::array<double, 3>> points;  // u, v, w
    for (int i = 0; i < s.size(); ++i) {
      const auto& site = s.sites()[static_cast<std::size_t>(i)];
      const int n = i == 0 ? 1 + count(rng) : count(rng);
      for (int k = 0; k < n; ++k) {
        std::uniform_int_distribution<std::int64_t> dt(-site.half_width_us, site.half_width_us);
        const std::int64_t d = (i == 0 && k == 0) ? 0 : dt(rng);
        ++counts[static_cast<std::size_t>(i)];
        sums[static_cast<std::size_t>(i)] += d;
        points.push_back({double(site.dx), double(site.dy), double(d) / 10'000.0});
      }
    }
    const QuadricFit fit = fit_quadric(s, counts, sums);
    Eigen::MatrixXd x(static_cast<Eigen::Index>(points.size()), 6);
    Eigen::VectorXd w(static_cast<Eigen::Index>(points.size()));
    for (std::size_t k = 0; k < points.size(); ++k) {
      const auto [u, v, ww] = points[k];
      x.row(static_cast<Eigen::Index>(k)) << u * u, v * v, u * v, u, v, 1;
      w(static_cast<Eigen::Index>(k)) = ww;
    }
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(x);
    qr.setThreshold(1e-9);
    ASSERT_EQ(fit.defined, qr.rank() == 6) << "seed " << seed << " trial " << trial;
    if (!fit.defined) continue;
    ++fitted;
    const Eigen::VectorXd coef = qr.solve(w);
    const double scale = 1.0 + coef.head<3>().cwiseAbs().maxCoeff();
    EXPECT_NEAR(fit.a, coef(0), 1e-9 * scale) << "seed " << seed << " trial " << trial;
    EXPECT_NEAR(fit.b, coef(1), 1e-9 * scale) << "seed " << seed << " trial " << trial;
    EXPECT_NEAR(fit.c, coef(2), 1e-9 * scale) << "seed " << seed << " trial " << trial;
    EXPECT_NEAR(fit.curvature, 4 * coef(0) * coef(1) - coef(2) * coef(2), 1e-8 * scale * scale);
  }
  EXPECT_GT(fitted, 100);
}

TEST(Quadric, ExactQuadraticSurfaceIsRecovered) {
  // Δt = 100 u² + 50 v² + 30 uv + 7 u − 3 v µs at the 9 inner sites: a = 0.01, b = 0.005, c = 0.003 per Lt.
  const Sphere s(2.0, 10'000, true);
  std::vector<std::int32_t> counts(13, 0);
  std::vector<std::int64_t> sums(13, 0);
  for (int i = 0; i < s.size(); ++i) {
    const auto& site = s.sites()[static_cast<std::size_t>(i)];
    if (std::abs(site.dx) == 2 || std::abs(site.dy) == 2) continue;
    const int u = site.dx, v = site.dy;
    counts[static_cast<std::size_t>(i)] = 2;
    sums[static_cast<std::size_t>(i)] = 2 * (100 * u * u + 50 * v * v + 30 * u * v + 7 * u - 3 * v);
  }
  const QuadricFit fit = fit_quadric(s, counts, sums);
  ASSERT_TRUE(fit.defined);
  EXPECT_NEAR(fit.a, 0.01, 1e-15);
  EXPECT_NEAR(fit.b, 0.005, 1e-15);
  EXPECT_NEAR(fit.c, 0.003, 1e-15);
  EXPECT_NEAR(fit.curvature, 4 * 0.01 * 0.005 - 0.003 * 0.003, 1e-15);
}

TEST(Quadric, PlaneGivesZeroCurvature) {
  const Sphere s(2.0, 10'000, true);
  std::vector<std::int32_t> counts(13, 1);
  std::vector<std::int64_t> sums(13, 0);
  for (int i = 0; i < s.size(); ++i) {
    const auto& site = s.sites()[static_cast<std::size_t>(i)];
    sums[static_cast<std::size_t>(i)] = site.half_width_us == 0 ? 0 : 1234 * site.dx - 567 * site.dy;
    if (site.half_width_us == 0) counts[static_cast<std::size_t>(i)] = 0;
  }
  const QuadricFit fit = fit_quadric(s, counts, sums);
  ASSERT_TRUE(fit.defined);
  EXPECT_NEAR(fit.curvature, 0.0, 1e-20);
}

// ---------------------------------------------------------------------------------------------- selection

std::vector<std::size_t> kept_indices(const std::vector<std::uint8_t>& keep) {
  std::vector<std::size_t> r;
  for (std::size_t i = 0; i < keep.size(); ++i)
    if (keep[i] != 0) r.push_back(i);
  return r;
}

TEST(Selection, KeepCount) {
  EXPECT_EQ(keep_count(0, 0.8), 0U);
  EXPECT_EQ(keep_count(10, 0.8), 8U);
  EXPECT_EQ(keep_count(11, 0.8), 9U);  // ⌈8.8⌉
  EXPECT_EQ(keep_count(5, 0.8), 4U);
  EXPECT_EQ(keep_count(3, 0.01), 1U);
  EXPECT_EQ(keep_count(7, 1.0), 7U);
  for (std::size_t n = 1; n < 2000; ++n) {
    EXPECT_EQ(keep_count(n, 0.8), (n * 8 + 9) / 10) << n;
  }
}

TEST(Selection, RulesOnAHandBuiltPopulation) {
  // median = 2 (values sorted: −10 0 1 2 3 3.5 40 50 ...), n = 10 → keep 8 with f = 0.8 ... use f = 0.5 → 5.
  const std::vector<double> c = {50.0, 1.0, -10.0, 2.0, 3.0, 0.0, 40.0, 3.5, 2.5, -0.5};
  std::vector<std::uint8_t> keep;
  // median: sorted −10 −0.5 0 1 2 2.5 3 3.5 40 50 → median (2 + 2.5)/2 = 2.25; distances: 1:1.25 2:0.25
  // 3:0.75 0:2.25 3.5:1.25 2.5:0.25 −0.5:2.75 → 5 smallest: 2, 2.5, 3, then 1 and 3.5 tie at 1.25 (both).
  auto r = select_consistent(c, 0.5, CurvatureRule::median, keep);
  EXPECT_EQ(kept_indices(keep), (std::vector<std::size_t>{1, 3, 4, 7, 8}));
  EXPECT_DOUBLE_EQ(r.centre, 2.25);
  EXPECT_DOUBLE_EQ(r.half_width, 1.25);
  // f = 0.4 → 4: tie at 1.25 between index 1 (value 1) and index 7 (3.5): the earlier index wins.
  select_consistent(c, 0.4, CurvatureRule::median, keep);
  EXPECT_EQ(kept_indices(keep), (std::vector<std::size_t>{1, 3, 4, 8}));
  // flattest: |c| smallest 4: 0, −0.5, 1, 2.
  r = select_consistent(c, 0.4, CurvatureRule::flattest, keep);
  EXPECT_EQ(kept_indices(keep), (std::vector<std::size_t>{1, 3, 5, 9}));
  EXPECT_DOUBLE_EQ(r.centre, 0.0);
  EXPECT_DOUBLE_EQ(r.half_width, 2.0);
  // shortest interval with 4 values: [2, 3.5] width 1.5 vs [0, 2] 2 vs [2.5, 40] ... → 2, 2.5, 3, 3.5.
  r = select_consistent(c, 0.4, CurvatureRule::shortest, keep);
  EXPECT_EQ(kept_indices(keep), (std::vector<std::size_t>{3, 4, 7, 8}));
  EXPECT_DOUBLE_EQ(r.lo, 2.0);
  EXPECT_DOUBLE_EQ(r.hi, 3.5);
  EXPECT_TRUE(r.contains(2.0));
  EXPECT_FALSE(r.contains(1.99));
  // keep_fraction 1 keeps everything.
  for (const auto rule : {CurvatureRule::median, CurvatureRule::shortest, CurvatureRule::flattest}) {
    select_consistent(c, 1.0, rule, keep);
    EXPECT_EQ(kept_indices(keep).size(), c.size());
  }
}

TEST(Selection, MedianRuleOnRandomPopulationsMatchesSorting) {
  const std::uint64_t seed = 77;
  std::mt19937_64 rng(seed);
  for (int trial = 0; trial < 200; ++trial) {
    const std::size_t n = 1 + rng() % 300;
    std::vector<double> c(n);
    for (auto& v : c) v = static_cast<double>(static_cast<int>(rng() % 21) - 10) * 0.5;  // many ties
    const double f = 0.05 + 0.95 * static_cast<double>(rng() % 1000) / 1000.0;
    std::vector<std::uint8_t> keep;
    const auto region = select_consistent(c, f, CurvatureRule::median, keep);
    std::vector<double> sorted = c;
    std::sort(sorted.begin(), sorted.end());
    const double med = n % 2 ? sorted[n / 2] : (sorted[n / 2 - 1] + sorted[n / 2]) / 2;
    ASSERT_DOUBLE_EQ(region.centre, med) << "seed " << seed << " trial " << trial;
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), 0U);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return std::abs(c[a] - med) < std::abs(c[b] - med); });
    const std::size_t k = keep_count(n, f);
    std::vector<std::uint8_t> expect(n, 0);
    for (std::size_t j = 0; j < k; ++j) expect[order[j]] = 1;
    ASSERT_EQ(keep, expect) << "seed " << seed << " trial " << trial;
  }
}

TEST(Selection, LargePopulationsMatchSorting) {
  // ≥ 4096 values take the radix pre-selection: clustered values, ties, ±0, ±inf-free wide magnitudes.
  const std::uint64_t seed = 4242;
  std::mt19937_64 rng(seed);
  for (int trial = 0; trial < 24; ++trial) {
    const std::size_t n = 4096 + rng() % 20000 + (trial % 2);
    std::vector<double> c(n);
    for (auto& v : c) {
      switch (rng() % 4) {
        case 0:
          v = static_cast<double>(static_cast<int>(rng() % 41) - 20) * 0.25;  // ties
          break;
        case 1:
          v = (rng() % 2 ? -0.0 : 0.0);
          break;
        case 2:
          v = std::ldexp(static_cast<double>(rng() % 1000) - 500.0, static_cast<int>(rng() % 80) - 40);
          break;
        default:
          v = 1e-3 * (static_cast<double>(rng() % 100000) - 30000.0);  // one dense cluster
      }
    }
    const double f = trial % 3 == 0 ? 0.8 : 0.05 + 0.95 * static_cast<double>(rng() % 1000) / 1000.0;
    for (const auto rule : {CurvatureRule::median, CurvatureRule::flattest}) {
      std::vector<std::uint8_t> keep;
      const auto region = select_consistent(c, f, rule, keep);
      std::vector<double> sorted = c;
      std::sort(sorted.begin(), sorted.end());
      const double med = n % 2 ? sorted[n / 2] : sorted[n / 2 - 1] + (sorted[n / 2] - sorted[n / 2 - 1]) / 2.0;
      const double centre = rule == CurvatureRule::median ? med : 0.0;
      ASSERT_EQ(region.centre, centre) << "seed " << seed << " trial " << trial;
      std::vector<std::size_t> order(n);
      std::iota(order.begin(), order.end(), 0U);
      std::stable_sort(order.begin(), order.end(),
                       [&](std::size_t a, std::size_t b) { return std::abs(c[a] - centre) < std::abs(c[b] - centre); });
      const std::size_t k = keep_count(n, f);
      ASSERT_EQ(region.half_width, std::abs(c[order[k - 1]] - centre)) << "seed " << seed << " trial " << trial;
      std::vector<std::uint8_t> expect(n, 0);
      for (std::size_t j = 0; j < k; ++j) expect[order[j]] = 1;
      ASSERT_EQ(keep, expect) << "seed " << seed << " trial " << trial;
    }
  }
}

// ---------------------------------------------------------------------------------------------- noise model

TEST(NoiseRate, ExposureOfThePaperBall) {
  const Sphere s(2.0, 10'000, true);
  // denoise.md §3.1: 40 + 4·34.64 + 4·28.28 ms = 0.2917 s·px (stream); half of it causal.
  const auto stream = make_exposure_model(s, CurvatureMode::stream, 30'000, kDavis346);
  EXPECT_NEAR(stream.interior_s, 0.040 + 4 * 0.034640 + 4 * 0.028284, 1e-9);
  EXPECT_NEAR(make_exposure_model(s, CurvatureMode::causal, 30'000, kDavis346).interior_s, stream.interior_s / 2,
              1e-12);
  // §4: 0.2117 s·px for 30 ms frames.
  EXPECT_NEAR(make_exposure_model(s, CurvatureMode::frames, 30'000, kDavis346).interior_s, 0.2117, 5e-4);
  double w = 0;
  for (const auto& [e, share] : stream.classes) w += share;
  EXPECT_NEAR(w, 1.0, 1e-12);
  EXPECT_EQ(stream.pixels, 346.0 * 260.0);
}

TEST(NoiseRate, PoissonAndThresholds) {
  EXPECT_NEAR(poisson_cdf(0, 2.0), std::exp(-2.0), 1e-15);
  EXPECT_NEAR(poisson_cdf(3, 1.5), std::exp(-1.5) * (1 + 1.5 + 1.125 + 0.5625), 1e-14);
  EXPECT_NEAR(poisson_sf(4, 0.2917 * 5), 0.061, 0.001);  // §3.1 table: 6.1 % at 5 Hz/px
  EXPECT_NEAR(poisson_sf(5, 0.2917 * 5), 0.0167, 0.0005);
  EXPECT_EQ(poisson_sf(0, 3.0), 1.0);
  const Sphere s(2.0, 10'000, true);
  const auto m = make_exposure_model(s, CurvatureMode::stream, 30'000, kDavis346);
  EXPECT_EQ(threshold_for_rate(0.0, m, 0.01), 2);
  EXPECT_EQ(threshold_for_rate(5.0, m, 0.01), 7);  // P(≥5 others) = 1.7 % > 1 %, P(≥6) < 1 %
  EXPECT_GT(threshold_for_rate(50.0, m, 0.01), threshold_for_rate(5.0, m, 0.01));
}

TEST(NoiseRate, EstimatorInvertsTheModel) {
  const Sphere s(2.0, 10'000, true);
  const auto m = make_exposure_model(s, CurvatureMode::stream, 30'000, kDavis346);
  for (const double rate : {0.1, 1.0, 5.0, 10.0}) {
    for (const std::int64_t th : {3, 5, 8}) {
      const double failed = m.pixels * 2.0 * rate * noise_fail_share(m, rate, th);
      const double est = estimate_noise_rate(failed, 2.0, m, th, -1.0);
      if (rate == 10.0 && th == 3) {
        // Beyond the maximiser of λ·share(λ) two rates explain the same failures: the smaller is returned
        // (the next period's higher threshold then resolves it).
        EXPECT_LT(est, rate);
        EXPECT_NEAR(m.pixels * 2.0 * est * noise_fail_share(m, est, th), failed, 1e-6 * failed);
        continue;
      }
      EXPECT_NEAR(est, rate, 1e-6 * rate) << rate << " " << th;
    }
  }
  EXPECT_EQ(estimate_noise_rate(100, 1.0, m, 1, 4.5), 4.5);  // threshold 1: nothing can fail
  EXPECT_EQ(estimate_noise_rate(0, 1.0, m, 5, 4.5), 0.0);
  // More failures than any rate explains: the maximiser, finite.
  const double huge = estimate_noise_rate(1e12, 1.0, m, 5, 0.0);
  EXPECT_TRUE(std::isfinite(huge));
  EXPECT_GT(huge, 5.0);
}

}  // namespace
}  // namespace evpipe::denoise
