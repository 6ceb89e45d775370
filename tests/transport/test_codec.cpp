// Records <-> generated LCM types <-> bytes: every field survives, the wire quaternion has qw >= 0, an unknown
// covariance is zeros + flag, foreign / truncated / invalid bytes are rejected with the field named.
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/text.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

namespace evpipe::transport {
namespace {

PoseRecord random_pose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PoseRecord r;
  r.seq = 42;
  r.t_us = 1'234'567'890;
  r.t_last_update_us = 1'234'000'000;
  r.utime_us = 1'700'000'000'123'456;
  r.camera_frame = "cam";
  r.model_frame = "roadheader";
  r.status = TrackingStatus::tracking;
  r.pose_valid = true;
  r.T_cam_model.t_cam_model_m = {u(rng), u(rng), 2.0 + u(rng)};
  r.T_cam_model.q_cam_model = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  r.covariance_known = true;
  for (std::size_t i = 0; i < 36; ++i) {
    r.covariance[i] = 1e-6 * u(rng);
  }
  r.window_events = 12345;
  r.inliers = 6789;
  r.sigma_px = 0.4375;
  r.latency_us = 812;
  r.source_connected = false;
  return r;
}

TEST(TransportCodec, PoseRoundTripsEveryField) {
  const unsigned seed = 20261121;
  std::printf("seed %u\n", seed);
  std::mt19937_64 rng(seed);
  for (int k = 0; k < 200; ++k) {
    const PoseRecord in = random_pose(rng);
    const std::vector<std::uint8_t> bytes = encode(in);
    const std::optional<PoseRecord> out = decode_pose(bytes.data(), bytes.size());
    ASSERT_TRUE(out.has_value());
    EXPECT_EQ(out->seq, in.seq);
    EXPECT_EQ(out->t_us, in.t_us);
    EXPECT_EQ(out->t_last_update_us, in.t_last_update_us);
    EXPECT_EQ(out->utime_us, in.utime_us);
    EXPECT_EQ(out->camera_frame, in.camera_frame);
    EXPECT_EQ(out->model_frame, in.model_frame);
    EXPECT_EQ(out->status, in.status);
    EXPECT_EQ(out->pose_valid, in.pose_valid);
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(out->T_cam_model.t_cam_model_m[i], in.T_cam_model.t_cam_model_m[i]);  // doubles are exact on LCM
    }
    // Same rotation; on the wire exactly camera::to_wire's numbers.
    const camera::WireQuaternion wi = camera::to_wire(in.T_cam_model.q_cam_model);
    const camera::WireQuaternion wo = camera::to_wire(out->T_cam_model.q_cam_model);
    EXPECT_NEAR(wo.qw, wi.qw, 1e-15);
    EXPECT_NEAR(wo.qx, wi.qx, 1e-15);
    EXPECT_NEAR(wo.qy, wi.qy, 1e-15);
    EXPECT_NEAR(wo.qz, wi.qz, 1e-15);
    EXPECT_TRUE(out->covariance_known);
    EXPECT_EQ(out->covariance, in.covariance);
    EXPECT_EQ(out->window_events, in.window_events);
    EXPECT_EQ(out->inliers, in.inliers);
    EXPECT_EQ(out->sigma_px, in.sigma_px);
    EXPECT_EQ(out->latency_us, in.latency_us);
    EXPECT_EQ(out->source_connected, in.source_connected);
  }
}

TEST(TransportCodec, WireQuaternionIsUnitWithNonNegativeQw) {
  PoseRecord r;
  // A quaternion with qw < 0 and not unit: the wire carries -q / |q| (same rotation, qw >= 0).
  r.T_cam_model.q_cam_model = Eigen::Quaterniond(-0.5, 0.5, -0.5, 0.5);  // Eigen ctor order: w x y z
  r.T_cam_model.q_cam_model.coeffs() *= 2.0;                             // to_wire normalises
  const evpipe::pose_t m = to_lcm(r);
  EXPECT_DOUBLE_EQ(m.orientation[0], 0.5);
  EXPECT_DOUBLE_EQ(m.orientation[1], -0.5);
  EXPECT_DOUBLE_EQ(m.orientation[2], 0.5);
  EXPECT_DOUBLE_EQ(m.orientation[3], -0.5);
  const double n2 = m.orientation[0] * m.orientation[0] + m.orientation[1] * m.orientation[1] +
                    m.orientation[2] * m.orientation[2] + m.orientation[3] * m.orientation[3];
  EXPECT_NEAR(n2, 1.0, 1e-15);

  // A 90 degree rotation about z: qw = qz = sqrt(1/2), in that order on the wire.
  r.T_cam_model.q_cam_model = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  const evpipe::pose_t z = to_lcm(r);
  EXPECT_NEAR(z.orientation[0], std::sqrt(0.5), 1e-15);
  EXPECT_EQ(z.orientation[1], 0.0);
  EXPECT_EQ(z.orientation[2], 0.0);
  EXPECT_NEAR(z.orientation[3], std::sqrt(0.5), 1e-15);
}

TEST(TransportCodec, UnknownCovarianceIsZerosAndFlag) {
  PoseRecord r;
  r.covariance_known = false;
  r.covariance.fill(3.0);  // stale numbers must not leak onto the wire
  const evpipe::pose_t m = to_lcm(r);
  EXPECT_FALSE(m.covariance_known);
  for (const double c : m.covariance) {
    EXPECT_EQ(c, 0.0);
  }
  const std::vector<std::uint8_t> bytes = encode(r);
  const auto out = decode_pose(bytes.data(), bytes.size());
  ASSERT_TRUE(out);
  EXPECT_FALSE(out->covariance_known);
  for (const double c : out->covariance) {
    EXPECT_EQ(c, 0.0);
  }
  // JSON says null rather than 36 zeros that look like certainty.
  EXPECT_NE(to_json(*out, "EVPIPE_POSE").find("\"covariance_known\":false,\"covariance\":null"), std::string::npos);
}

TEST(TransportCodec, StatusWireValues) {
  EXPECT_EQ(evpipe::pose_t::STATUS_INITIALISING, static_cast<std::int8_t>(TrackingStatus::initialising));
  EXPECT_EQ(evpipe::pose_t::STATUS_TRACKING, static_cast<std::int8_t>(TrackingStatus::tracking));
  EXPECT_EQ(evpipe::pose_t::STATUS_LOST, static_cast<std::int8_t>(TrackingStatus::lost));
  EXPECT_EQ(evpipe::pose_t::STATUS_HOLDING, static_cast<std::int8_t>(TrackingStatus::holding));
  EXPECT_EQ(to_string(TrackingStatus::holding), "holding");
  for (const auto s :
       {TrackingStatus::initialising, TrackingStatus::tracking, TrackingStatus::lost, TrackingStatus::holding}) {
    PoseRecord r;
    r.status = s;
    const auto bytes = encode(r);
    EXPECT_EQ(decode_pose(bytes.data(), bytes.size())->status, s);
  }
  // A value outside the four is refused with the field named.
  evpipe::pose_t m = to_lcm(PoseRecord{});
  m.status = 4;
  EXPECT_THROW((void)from_lcm(m), DecodeError);
}

TEST(TransportCodec, HoldingPoseCarriesTheTimeOfItsLastMeasurement) {
  PoseRecord r;
  r.t_us = 5'015'000;
  r.t_last_update_us = 3'015'000;  // held for 2 s
  r.status = TrackingStatus::holding;
  r.pose_valid = true;
  const auto bytes = encode(r);
  const auto out = decode_pose(bytes.data(), bytes.size());
  ASSERT_TRUE(out);
  EXPECT_EQ(out->status, TrackingStatus::holding);
  EXPECT_TRUE(out->pose_valid);
  EXPECT_EQ(out->t_last_update_us, 3'015'000);
  const std::string json = to_json(*out, "EVPIPE_POSE");
  EXPECT_NE(json.find("\"t_us\":5015000,\"t_last_update_us\":3015000,"), std::string::npos) << json;
  EXPECT_NE(json.find("\"status\":\"holding\",\"pose_valid\":true"), std::string::npos) << json;
  const std::string text = to_text(*out, "EVPIPE_POSE");
  EXPECT_NE(text.find(" holding t_m="), std::string::npos) << text;
  EXPECT_NE(text.find(" measured_t=3.015000 s "), std::string::npos) << text;
}

StatsRecord sample_stats() {
  StatsRecord s;
  s.seq = 7;
  s.utime_us = 1'700'000'001'000'000;
  s.interval_us = 1'000'000;
  s.t_us = 98'765'432;
  s.uptime_us = 7'000'123;
  s.source = "live";
  s.source_connected = false;
  s.source_reconnects = 3;
  s.status = TrackingStatus::lost;
  s.poses_published = 210;
  s.publish_failures = 4;
  s.latency_p50_us = 350.5;
  s.latency_p99_us = 1800.25;
  s.stages = {{"source", 1000, 1000, 0, 10, 500, 1.5, 2.5, 3.5},
              {"denoise", 1000, 420, 17, 10, 9000, 800.0, 950.0, 1200.0},
              {"pose", 420, 420, 0, 33, 30000, 900.0, 1500.0, 2100.0},
              {"publish", 33, 33, 0, 33, 66, 2.0, 3.0, 4.0}};
  s.queues = {{"batches", 64, 3, 12, 1000, 17, 1'000'000, 24'576, 250'000}, {"windows", 16, 0, 2, 330, 0, 0, 0, 0}};
  s.denoise_figures = {{"noise_rate_hz", 1.125}, {"density_threshold_used", 4}};
  return s;
}

TEST(TransportCodec, StatsRoundTripsEveryField) {
  const StatsRecord in = sample_stats();
  const auto bytes = encode(in);
  const auto out = decode_stats(bytes.data(), bytes.size());
  ASSERT_TRUE(out);
  EXPECT_EQ(out->seq, in.seq);
  EXPECT_EQ(out->utime_us, in.utime_us);
  EXPECT_EQ(out->interval_us, in.interval_us);
  EXPECT_EQ(out->t_us, in.t_us);
  EXPECT_EQ(out->uptime_us, in.uptime_us);
  EXPECT_EQ(out->source, in.source);
  EXPECT_EQ(out->source_connected, in.source_connected);
  EXPECT_EQ(out->source_reconnects, in.source_reconnects);
  EXPECT_EQ(out->status, in.status);
  EXPECT_EQ(out->poses_published, in.poses_published);
  EXPECT_EQ(out->publish_failures, in.publish_failures);
  EXPECT_EQ(out->latency_p50_us, in.latency_p50_us);
  EXPECT_EQ(out->latency_p99_us, in.latency_p99_us);
  ASSERT_EQ(out->stages.size(), in.stages.size());
  for (std::size_t i = 0; i < in.stages.size(); ++i) {
    const auto& a = in.stages[i];
    const auto& b = out->stages[i];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.events_in, a.events_in);
    EXPECT_EQ(b.events_kept, a.events_kept);
    EXPECT_EQ(b.events_dropped, a.events_dropped);
    EXPECT_EQ(b.packets_in, a.packets_in);
    EXPECT_EQ(b.busy_us, a.busy_us);
    EXPECT_EQ(b.proc_p50_us, a.proc_p50_us);
    EXPECT_EQ(b.proc_p99_us, a.proc_p99_us);
    EXPECT_EQ(b.proc_max_us, a.proc_max_us);
  }
  ASSERT_EQ(out->queues.size(), in.queues.size());
  for (std::size_t i = 0; i < in.queues.size(); ++i) {
    const auto& a = in.queues[i];
    const auto& b = out->queues[i];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.capacity, a.capacity);
    EXPECT_EQ(b.fill, a.fill);
    EXPECT_EQ(b.fill_max, a.fill_max);
    EXPECT_EQ(b.pushed, a.pushed);
    EXPECT_EQ(b.dropped, a.dropped);
    EXPECT_EQ(b.events_budget, a.events_budget);
    EXPECT_EQ(b.events, a.events);
    EXPECT_EQ(b.events_max, a.events_max);
  }
  EXPECT_EQ(out->denoise_figures, in.denoise_figures);
}

TEST(TransportCodec, ForeignAndTruncatedBytesAreNotDecoded) {
  const auto pose_bytes = encode(PoseRecord{});
  const auto stats_bytes = encode(sample_stats());
  EXPECT_FALSE(decode_pose(stats_bytes.data(), stats_bytes.size()));  // other fingerprint
  EXPECT_FALSE(decode_stats(pose_bytes.data(), pose_bytes.size()));
  EXPECT_FALSE(decode_pose(pose_bytes.data(), pose_bytes.size() - 1));  // truncated
  EXPECT_FALSE(decode_stats(stats_bytes.data(), 20));
  EXPECT_FALSE(decode_pose(nullptr, 0));
  EXPECT_FALSE(decode_pose(pose_bytes.data(), 4));
}

TEST(TransportCodec, ANegativeArrayLengthIsNotDecoded) {
  // Right fingerprint, but the array lengths say -1 (another publisher's bug): no exception, no allocation storm.
  for (const int field : {0, 1, 2}) {
    evpipe::stats_t m = to_lcm(sample_stats());
    if (field == 0) m.num_stages = -1, m.stages.clear();
    if (field == 1) m.num_queues = -1, m.queues.clear();
    if (field == 2) m.num_denoise_figures = 0, m.denoise_figure_names.clear(), m.denoise_figures.clear();
    std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
    ASSERT_GE(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), 0) << field;
    // The generated encoder refuses a negative string-array length: write it over the last field (big endian).
    if (field == 2) std::fill(bytes.end() - 4, bytes.end(), std::uint8_t{0xff});
    std::optional<StatsRecord> out;
    EXPECT_NO_THROW(out = decode_stats(bytes.data(), bytes.size())) << field;
    EXPECT_FALSE(out) << field;
  }
}

TEST(TransportCodec, InvalidContentNamesTheField) {
  evpipe::pose_t m = to_lcm(PoseRecord{});
  m.orientation[0] = m.orientation[1] = m.orientation[2] = m.orientation[3] = 0.0;
  try {
    (void)from_lcm(m);
    FAIL() << "zero quaternion accepted";
  } catch (const DecodeError& e) {
    EXPECT_NE(std::string(e.what()).find("pose_t.orientation"), std::string::npos) << e.what();
  }
  m = to_lcm(PoseRecord{});
  m.status = 7;
  try {
    (void)from_lcm(m);
    FAIL() << "status 7 accepted";
  } catch (const DecodeError& e) {
    EXPECT_NE(std::string(e.what()).find("pose_t.status"), std::string::npos) << e.what();
  }
  m = to_lcm(PoseRecord{});
  m.position_m[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)from_lcm(m), DecodeError);

  evpipe::stats_t s = to_lcm(sample_stats());
  s.num_stages = 9;  // does not match the array (encode() would refuse to write such a message)
  try {
    (void)from_lcm(s);
    FAIL() << "num_stages mismatch accepted";
  } catch (const DecodeError& e) {
    EXPECT_NE(std::string(e.what()).find("stats_t.num_stages"), std::string::npos) << e.what();
  }
}

TEST(TransportText, JsonLines) {
  PoseRecord p;
  p.seq = 3;
  p.t_us = 30000;
  p.status = TrackingStatus::tracking;
  p.T_cam_model.t_cam_model_m = {0.25, -0.5, 2.0};
  p.sigma_px = std::numeric_limits<double>::infinity();
  p.model_frame = "a\"b";
  const std::string j = to_json(p, "EVPIPE_POSE");
  EXPECT_EQ(j.find('\n'), std::string::npos);
  EXPECT_NE(j.find("\"channel\":\"EVPIPE_POSE\",\"type\":\"evpipe.pose_t\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"seq\":3,"), std::string::npos) << j;
  EXPECT_NE(j.find("\"status\":\"tracking\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"position_m\":[0.25,-0.5,2]"), std::string::npos) << j;
  EXPECT_NE(j.find("\"orientation\":[1,0,0,0]"), std::string::npos) << j;
  EXPECT_NE(j.find("\"sigma_px\":null"), std::string::npos) << j;
  EXPECT_NE(j.find("\"model_frame\":\"a\\\"b\""), std::string::npos) << j;

  const std::string s = to_json(sample_stats(), "EVPIPE_STATS");
  EXPECT_NE(s.find("\"type\":\"evpipe.stats_t\""), std::string::npos) << s;
  EXPECT_NE(s.find("{\"name\":\"denoise\",\"events_in\":1000,\"events_kept\":420,\"events_dropped\":17"),
            std::string::npos)
      << s;
  EXPECT_NE(s.find("{\"name\":\"batches\",\"capacity\":64,\"fill\":3,\"fill_max\":12,\"pushed\":1000,"
                   "\"dropped\":17,\"events_budget\":1000000,\"events\":24576,\"events_max\":250000}"),
            std::string::npos)
      << s;
  EXPECT_NE(s.find("\"denoise_figures\":{\"noise_rate_hz\":1.125,\"density_threshold_used\":4}}"), std::string::npos)
      << s;
}

}  // namespace
}  // namespace evpipe::transport
