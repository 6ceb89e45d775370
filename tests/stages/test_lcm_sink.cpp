// The publish stage's work (stages::LcmSink) on a real LCM without a network (memq://): each estimate goes out
// through the one mapping (to_record), and the camera-lost policy: when the live source is lost, a LOST pose (the
// last good pose, source_connected false) goes out at once, not only when windows resume.

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <memory>

#include "evpipe/stages/lcm_sink.hpp"
#include "evpipe/stages/pose_processor.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;
using namespace evpipe::stages;

namespace {

std::unique_ptr<PoseProcessor> sample_processor() {
  const auto data = evpipe::testing::source_dir() / "tests" / "data";
  PoseProcessorOptions o;
  o.camera = (data / "roadheader-sample.camera.yaml").string();
  o.model = (data / "roadheader-sample.model.yaml").string();
  return PoseProcessor::create(o);
}

PoseSample tracked_at(std::int64_t t_us) {
  PoseSample s;
  s.estimate.t_us = t_us;
  s.estimate.t_last_update_us = t_us;
  s.estimate.status = pose::TrackStatus::tracking;
  s.estimate.pose_valid = true;
  s.estimate.T_cam_model.t_cam_model_m = {0.1, 0.2, 2.0};
  s.estimate.covariance_known = true;
  s.estimate.covariance = pose::Covariance6::Identity() * 1e-4;
  s.estimate.inliers = 123;
  s.window_ready = Clock::now();
  return s;
}

PipelineStats stats_with(SourceState state) {
  PipelineStats s;
  s.source.state = state;
  return s;
}

}  // namespace

TEST(LcmSink, PublishesEachPoseAndALostPoseAtOnceWhenTheCameraGoes) {
  auto lcm = std::make_shared<::lcm::LCM>("memq://");
  ASSERT_TRUE(lcm->good());
  transport::LcmPublisher publisher(lcm, "EVPIPE_POSE", "EVPIPE_STATS");
  transport::LcmCapture capture(lcm);
  capture.subscribe("EVPIPE_.*");
  auto processor = sample_processor();
  LcmSink sink(&publisher, processor.get(), true, false);

  sink.publish_stats(stats_with(SourceState::running));
  sink.publish_pose(tracked_at(30'000));
  EXPECT_EQ(sink.latest_status(), pose::TrackStatus::tracking);
  sink.publish_stats(stats_with(SourceState::lost));
  EXPECT_EQ(sink.latest_status(), pose::TrackStatus::lost);
  sink.publish_stats(stats_with(SourceState::lost));     // still lost: no second LOST pose
  sink.publish_stats(stats_with(SourceState::running));  // back: the next windows say what the pose is
  ASSERT_EQ(capture.wait_for(6, std::chrono::seconds(5)), 6u);

  const auto poses = capture.poses("EVPIPE_POSE");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].t_us, 30'000);
  EXPECT_EQ(poses[0].status, pose::TrackStatus::tracking);
  EXPECT_TRUE(poses[0].pose_valid);
  EXPECT_TRUE(poses[0].covariance_known);
  EXPECT_DOUBLE_EQ(poses[0].covariance[0], 1e-4);
  EXPECT_EQ(poses[0].inliers, 123);
  EXPECT_TRUE(poses[0].source_connected);
  // The LOST pose: the last sensor time and the last good pose, not valid, no covariance, camera gone.
  EXPECT_EQ(poses[1].t_us, 30'000);
  EXPECT_EQ(poses[1].status, pose::TrackStatus::lost);
  EXPECT_FALSE(poses[1].pose_valid);
  EXPECT_FALSE(poses[1].covariance_known);
  EXPECT_DOUBLE_EQ(poses[1].T_cam_model.t_cam_model_m.z(), 2.0);
  EXPECT_FALSE(poses[1].source_connected);

  const auto stats = capture.stats("EVPIPE_STATS");
  ASSERT_EQ(stats.size(), 4u);
  EXPECT_TRUE(stats[0].source_connected);
  EXPECT_EQ(stats[0].source, "live");
  EXPECT_FALSE(stats[1].source_connected);
  EXPECT_EQ(stats[1].status, pose::TrackStatus::lost);
  EXPECT_TRUE(stats[3].source_connected);
}

TEST(LcmSink, ToRecordSendsACovarianceOnlyWithAValidPose) {
  auto s = tracked_at(60'000);
  EXPECT_TRUE(to_record(s.estimate, true).covariance_known);
  s.estimate.pose_valid = false;
  s.estimate.status = pose::TrackStatus::lost;
  const auto r = to_record(s.estimate, false);
  EXPECT_FALSE(r.covariance_known);
  EXPECT_FALSE(r.pose_valid);
  EXPECT_EQ(r.status, pose::TrackStatus::lost);
  EXPECT_FALSE(r.source_connected);
}
