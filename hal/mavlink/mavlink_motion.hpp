#pragma once
// hal::Motion over MAVLink 2: the companion computer (system 1, component 191 MAV_COMP_ID_ONBOARD_COMPUTER
// by default) commands viewpoints to the autopilot with SET_POSITION_TARGET_LOCAL_NED (position + yaw;
// velocity, acceleration and yaw rate masked out), streamed at setpoint_period_s as offboard/guided modes
// require, sends its own HEARTBEAT every heartbeat_period_s, asks the autopilot for LOCAL_POSITION_NED and
// ATTITUDE at pose_rate_hz (COMMAND_LONG MAV_CMD_SET_MESSAGE_INTERVAL, answered by COMMAND_ACK), and
// reads the pose from LOCAL_POSITION_NED + ATTITUDE or from ODOMETRY.
//
// Link loss: no HEARTBEAT from the autopilot for link_loss_timeout_s (counted from start() before the
// first one) -> fault() == kLinkLost, command() refuses with kLinkLost, and the setpoint stream switches to
// "hold": the last reported position and heading, so a one-way outage cannot leave the vehicle flying to
// a stale target. (A dead link in both directions is the autopilot's own offboard-loss failsafe.) The
// fault stays until heartbeats are back and a new command is accepted.
//
// Everything is sized at construction; update() never allocates. The parser takes at most
// kMaxBytesPerUpdate bytes per update(), so a flood costs bounded time and the OS drops the excess.
#include <cstdint>

#include "hal/clock.hpp"
#include "hal/mavlink/frame.hpp"
#include "hal/mavlink/link.hpp"
#include "hal/mavlink/ned_frame.hpp"
#include "hal/motion.hpp"

namespace vantage::hal::mavlink {

struct MavlinkMotionConfig {
  std::uint8_t system_id = 1;
  std::uint8_t component_id = 191;  // MAV_COMP_ID_ONBOARD_COMPUTER
  std::uint8_t target_system = 1;
  std::uint8_t target_component = 1;  // MAV_COMP_ID_AUTOPILOT1
  double heartbeat_period_s = 1.0;
  double setpoint_period_s = 0.1;
  double link_loss_timeout_s = 3.0;
  double pose_rate_hz = 20.0;
  double arrive_tolerance_m = 0.15;
  double arrive_yaw_tolerance_rad = 0.05;
  double default_tilt_rad = 0.0;  // camera tilt reported before any command
  NedFrame frame;
  bool signing = false;
  SigningKey signing_key{};
  std::uint8_t signing_link_id = 1;

  // Empty on success, else which field is wrong.
  const char* validate() const;
};

struct MotionLinkStats {
  std::uint64_t heartbeats = 0;
  std::uint64_t poses = 0;
  std::uint64_t setpoints_sent = 0;
  std::uint64_t commands_acked = 0;
  std::uint64_t commands_refused = 0;  // COMMAND_ACK with a result other than accepted
  std::uint64_t foreign_frames = 0;    // valid frames from other systems (ignored)
  std::uint64_t signature_rejected = 0;
  std::uint64_t replay_rejected = 0;
  std::uint64_t unsigned_rejected = 0;
  std::uint64_t send_failures = 0;
  std::uint64_t link_errors = 0;
  std::uint64_t link_losses = 0;
};

class MavlinkMotion final : public Motion {
 public:
  static constexpr std::size_t kMaxBytesPerUpdate = 16 * 1024;

  MavlinkMotion(ByteLink& link, const Clock& clock, const MavlinkMotionConfig& config);

  // Sends the first heartbeat (the vehicle learns our address from it) and starts the link-loss timer.
  void start();

  MotionFault command(const Viewpoint& target) override;
  void update(double dt_s) override;
  PoseReport current_pose() const override { return pose_; }
  bool arrived() const override;
  MotionFault fault() const override { return fault_; }

  bool link_up() const { return heartbeat_seen_ && !link_lost_; }
  const MotionLinkStats& stats() const { return stats_; }
  const ParserStats& parser_stats() const { return parser_.stats(); }
  // Heading and NED position of the current setpoint (for tests and logs).
  const Eigen::Vector3d& setpoint_ned() const { return setpoint_ned_; }
  double setpoint_yaw_rad() const { return setpoint_yaw_rad_; }
  bool holding() const { return holding_; }

 private:
  void poll_link(std::int64_t now_ns);
  void handle(const Frame& frame, std::int64_t now_ns);
  void send_heartbeat();
  void send_setpoint();
  void request_pose_stream();
  void refresh_pose(std::int64_t now_ns);
  template <typename Message>
  void send(const Message& message);

  ByteLink& link_;
  const Clock& clock_;
  MavlinkMotionConfig config_;
  FrameWriter writer_;
  FrameParser parser_;
  SignatureVerifier verifier_;
  std::array<std::uint8_t, kMaxFrameBytes> tx_{};
  std::array<std::uint8_t, 2048> rx_{};

  std::int64_t start_ns_ = 0;
  std::int64_t last_heartbeat_rx_ns_ = 0;
  std::int64_t last_heartbeat_tx_ns_ = 0;
  std::int64_t last_setpoint_tx_ns_ = 0;
  std::int64_t command_ns_ = 0;
  bool started_ = false;
  bool heartbeat_seen_ = false;
  bool link_lost_ = false;
  bool stream_requested_ = false;

  bool have_setpoint_ = false;
  bool holding_ = false;
  Eigen::Vector3d setpoint_ned_ = Eigen::Vector3d::Zero();
  double setpoint_yaw_rad_ = 0.0;
  double tilt_rad_ = 0.0;

  bool have_position_ = false;
  bool have_attitude_ = false;
  Eigen::Vector3d position_ned_ = Eigen::Vector3d::Zero();
  double yaw_ned_rad_ = 0.0;
  std::int64_t pose_rx_ns_ = 0;
  PoseReport pose_;

  MotionFault fault_ = MotionFault::kNone;
  MotionLinkStats stats_;
};

}  // namespace vantage::hal::mavlink
