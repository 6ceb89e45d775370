// FLANN is used header-only (Debian's FLANN 1.9.2); its serialisation header needs lz4 at link time.
#include <flann/flann.hpp>

#include "evpipe/denoise/neighbourhood.hpp"

namespace evpipe::denoise {

struct FlannBallIndex::Impl {
  explicit Impl(const Sphere& s) : sphere(s), result(static_cast<double>(s.limit()) + 0.5) {}
  const Sphere& sphere;
  std::vector<double> points;           // (Lt·x, Lt·y, t − t0) per indexed event
  std::vector<std::uint32_t> position;  // index position → position in the built span
  std::int64_t t0_us = 0;
  std::unique_ptr<flann::KDTreeSingleIndex<flann::L2<double>>> index;
  mutable flann::RadiusResultSet<double> result;
  mutable std::vector<size_t> found;
  mutable std::vector<double> dists;
};

FlannBallIndex::FlannBallIndex(const Sphere& sphere) : impl_(std::make_unique<Impl>(sphere)) {}
FlannBallIndex::~FlannBallIndex() = default;

void FlannBallIndex::build(EventSpan events, const SensorGeometry& geometry) {
  Impl& m = *impl_;
  m.points.clear();
  m.position.clear();
  m.index.reset();
  m.t0_us = events.empty() ? 0 : events.front().t_us;
  const auto lt = static_cast<double>(m.sphere.lt_us());
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    if (!geometry.contains(e.x, e.y)) continue;
    // Integers below 2⁵³: every squared distance within the ball's reach is exact.
    m.points.push_back(lt * e.x);
    m.points.push_back(lt * e.y);
    m.points.push_back(static_cast<double>(e.t_us - m.t0_us));
    m.position.push_back(static_cast<std::uint32_t>(i));
  }
  if (m.position.empty()) return;
  flann::Matrix<double> data(m.points.data(), m.position.size(), 3);
  m.index = std::make_unique<flann::KDTreeSingleIndex<flann::L2<double>>>(data, flann::KDTreeSingleIndexParams());
  m.index->buildIndex();
}

void FlannBallIndex::ball(const Event& centre, std::vector<std::uint32_t>& out) const {
  const Impl& m = *impl_;
  out.clear();
  if (!m.index) return;
  const auto lt = static_cast<double>(m.sphere.lt_us());
  const double query[3] = {lt * centre.x, lt * centre.y, static_cast<double>(centre.t_us - m.t0_us)};
  // FLANN's radius result set keeps dist < radius (strict); the squared distances are integers, so
  // limit + 0.5 accepts exactly dist ≤ limit. radiusSearch() would narrow the radius to float (4·10⁸ + 0.5
  // rounds to 4·10⁸ and loses the boundary sites), hence the result set is used directly.
  m.result.clear();
  m.index->findNeighbors(m.result, query, flann::SearchParams(flann::FLANN_CHECKS_UNLIMITED, 0.0F, false));
  const std::size_t n = m.result.size();
  m.found.resize(n);
  m.dists.resize(n);
  m.result.copy(m.found.data(), m.dists.data(), n, false);
  out.reserve(n);
  for (const size_t k : m.found) out.push_back(m.position[k]);
}

}  // namespace evpipe::denoise
