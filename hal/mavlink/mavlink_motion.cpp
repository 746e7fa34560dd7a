#include "hal/mavlink/mavlink_motion.hpp"

#include <cmath>

namespace vantage::hal::mavlink {
namespace {


std::int64_t to_ns(double seconds) { return static_cast<std::int64_t>(seconds * 1e9); }

double wrap_angle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

}  // namespace

const char* MavlinkMotionConfig::validate() const {
  if (!(heartbeat_period_s > 0.0 && heartbeat_period_s <= 5.0)) return "heartbeat_period_s must be in (0, 5]";
  if (!(setpoint_period_s > 0.0 && setpoint_period_s <= 1.0)) return "setpoint_period_s must be in (0, 1]";
  if (!(link_loss_timeout_s > heartbeat_period_s && link_loss_timeout_s <= 60.0)) {
    return "link_loss_timeout_s must exceed heartbeat_period_s and be at most 60";
  }
  if (!(pose_rate_hz > 0.0 && pose_rate_hz <= 200.0)) return "pose_rate_hz must be in (0, 200]";
  if (!(arrive_tolerance_m > 0.0) || !std::isfinite(arrive_tolerance_m)) return "arrive_tolerance_m must be positive";
  if (!(arrive_yaw_tolerance_rad > 0.0 && arrive_yaw_tolerance_rad < M_PI)) return "arrive_yaw_tolerance_rad must be in (0, pi)";
  if (!std::isfinite(default_tilt_rad) || std::fabs(default_tilt_rad) >= M_PI / 2) return "default_tilt_rad must be in (-pi/2, pi/2)";
  if (!frame.world_origin_ned.allFinite()) return "world_origin_ned must be finite";
  return "";
}

MavlinkMotion::MavlinkMotion(ByteLink& link, const Clock& clock, const MavlinkMotionConfig& config)
    : link_(link),
      clock_(clock),
      config_(config),
      writer_(config.system_id, config.component_id),
      verifier_(config.signing_key),
      tilt_rad_(config.default_tilt_rad) {
  if (config_.signing) writer_.enable_signing(config_.signing_key, config_.signing_link_id);
}

template <typename Message>
void MavlinkMotion::send(const Message& message) {
  const std::size_t size = writer_.write(message, tx_.data());
  if (!link_.send(tx_.data(), size)) ++stats_.send_failures;
}

void MavlinkMotion::start() {
  start_ns_ = clock_.now_ns();
  started_ = true;
  send_heartbeat();
  last_heartbeat_tx_ns_ = start_ns_;
}

void MavlinkMotion::send_heartbeat() {
  Heartbeat hb;
  hb.type = kMavTypeOnboardController;
  hb.autopilot = kMavAutopilotInvalid;
  hb.system_status = kMavStateActive;
  hb.mavlink_version = 3;
  send(hb);
}

void MavlinkMotion::request_pose_stream() {
  const float interval_us = static_cast<float>(1e6 / config_.pose_rate_hz);
  for (std::uint32_t message : {static_cast<std::uint32_t>(kLocalPositionNedId), static_cast<std::uint32_t>(kAttitudeId)}) {
    CommandLong cmd;
    cmd.command = kMavCmdSetMessageInterval;
    cmd.param[0] = static_cast<float>(message);
    cmd.param[1] = interval_us;
    cmd.target_system = config_.target_system;
    cmd.target_component = config_.target_component;
    send(cmd);
  }
}

void MavlinkMotion::send_setpoint() {
  SetPositionTargetLocalNed sp;
  sp.time_boot_ms = static_cast<std::uint32_t>((clock_.now_ns() - start_ns_) / 1'000'000);
  sp.x = static_cast<float>(setpoint_ned_.x());
  sp.y = static_cast<float>(setpoint_ned_.y());
  sp.z = static_cast<float>(setpoint_ned_.z());
  sp.yaw = static_cast<float>(setpoint_yaw_rad_);
  sp.type_mask = kIgnoreVelocity | kIgnoreAcceleration | kIgnoreYawRate;
  sp.target_system = config_.target_system;
  sp.target_component = config_.target_component;
  sp.coordinate_frame = kMavFrameLocalNed;
  send(sp);
  ++stats_.setpoints_sent;
}

MotionFault MavlinkMotion::command(const Viewpoint& target) {
  if (!target.position_world.allFinite() || !target.R_world_cam.allFinite()) return MotionFault::kNonFiniteTarget;
  if (link_lost_ || !heartbeat_seen_) return MotionFault::kLinkLost;
  double yaw = 0.0;
  double tilt = 0.0;
  // A camera looking straight up or down has no heading to command over this link.
  if (!heading_and_tilt(target, &yaw, &tilt)) return MotionFault::kRejected;
  setpoint_ned_ = config_.frame.ned_from_world(target.position_world);
  setpoint_yaw_rad_ = yaw;
  tilt_rad_ = tilt;
  have_setpoint_ = true;
  holding_ = false;
  fault_ = MotionFault::kNone;
  command_ns_ = clock_.now_ns();
  send_setpoint();
  last_setpoint_tx_ns_ = command_ns_;
  return MotionFault::kNone;
}

void MavlinkMotion::update(double /*dt_s: the link runs on the clock*/) {
  if (!started_) start();
  const std::int64_t now = clock_.now_ns();
  poll_link(now);

  const std::int64_t since_heartbeat = now - (heartbeat_seen_ ? last_heartbeat_rx_ns_ : start_ns_);
  if (!link_lost_ && since_heartbeat > to_ns(config_.link_loss_timeout_s)) {
    link_lost_ = true;
    fault_ = MotionFault::kLinkLost;
    ++stats_.link_losses;
    if (have_position_) {
      // Hold where the vehicle last said it was.
      setpoint_ned_ = position_ned_;
      setpoint_yaw_rad_ = yaw_ned_rad_;
      have_setpoint_ = true;
      holding_ = true;
    }
  }
  if (now - last_heartbeat_tx_ns_ >= to_ns(config_.heartbeat_period_s)) {
    send_heartbeat();
    last_heartbeat_tx_ns_ = now;
  }
  if (have_setpoint_ && now - last_setpoint_tx_ns_ >= to_ns(config_.setpoint_period_s)) {
    send_setpoint();
    last_setpoint_tx_ns_ = now;
  }
}

void MavlinkMotion::poll_link(std::int64_t now_ns) {
  std::size_t budget = kMaxBytesPerUpdate;
  while (budget > 0) {
    const long got = link_.receive(rx_.data(), rx_.size() < budget ? rx_.size() : budget);
    if (got < 0) {
      ++stats_.link_errors;
      break;
    }
    if (got == 0) break;
    budget -= static_cast<std::size_t>(got);
    const std::uint8_t* data = rx_.data();
    std::size_t left = static_cast<std::size_t>(got);
    while (left > 0) {
      const std::size_t taken = parser_.write(data, left);
      data += taken;
      left -= taken;
      Frame frame;
      while (parser_.next(&frame)) handle(frame, now_ns);
    }
  }
  refresh_pose(now_ns);
}

void MavlinkMotion::handle(const Frame& frame, std::int64_t now_ns) {
  if (config_.signing) {
    switch (verifier_.check(frame, signing_timestamp_now())) {
      case SignatureVerdict::kAccepted: break;
      case SignatureVerdict::kUnsigned: ++stats_.unsigned_rejected; return;
      case SignatureVerdict::kReplay:
      case SignatureVerdict::kStale: ++stats_.replay_rejected; return;
      case SignatureVerdict::kBadSignature:
      case SignatureVerdict::kTooManyStreams: ++stats_.signature_rejected; return;
    }
  }
  if (frame.system_id != config_.target_system) {
    ++stats_.foreign_frames;
    return;
  }
  switch (frame.message_id) {
    case kHeartbeatId: {
      if (frame.component_id != config_.target_component) {
        ++stats_.foreign_frames;
        return;
      }
      ++stats_.heartbeats;
      last_heartbeat_rx_ns_ = now_ns;
      if (!heartbeat_seen_ || link_lost_) stream_requested_ = false;
      heartbeat_seen_ = true;
      link_lost_ = false;  // fault_ stays until a new command is accepted
      if (!stream_requested_) {
        request_pose_stream();
        stream_requested_ = true;
      }
      return;
    }
    case kLocalPositionNedId: {
      LocalPositionNed m;
      decode(frame.payload, &m);
      const Eigen::Vector3d p(m.x, m.y, m.z);
      if (!p.allFinite()) return;
      position_ned_ = p;
      have_position_ = true;
      pose_rx_ns_ = now_ns;
      ++stats_.poses;
      return;
    }
    case kAttitudeId: {
      Attitude m;
      decode(frame.payload, &m);
      if (!std::isfinite(m.yaw)) return;
      yaw_ned_rad_ = m.yaw;
      have_attitude_ = true;
      return;
    }
    case kOdometryId: {
      Odometry m;
      decode(frame.payload, &m);
      if (m.frame_id != kMavFrameLocalNed) return;
      const Eigen::Vector3d p(m.x, m.y, m.z);
      const double w = m.q[0], x = m.q[1], y = m.q[2], z = m.q[3];
      const double yaw = std::atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
      if (!p.allFinite() || !std::isfinite(yaw)) return;
      position_ned_ = p;
      yaw_ned_rad_ = yaw;
      have_position_ = true;
      have_attitude_ = true;
      pose_rx_ns_ = now_ns;
      ++stats_.poses;
      return;
    }
    case kCommandAckId: {
      CommandAck m;
      decode(frame.payload, &m);
      if (m.result == kMavResultAccepted) {
        ++stats_.commands_acked;
      } else {
        ++stats_.commands_refused;
      }
      return;
    }
    default:
      return;  // known but not for us (e.g. another companion's setpoints)
  }
}

void MavlinkMotion::refresh_pose(std::int64_t now_ns) {
  (void)now_ns;
  if (!have_position_ || !have_attitude_) return;
  pose_.pose = viewpoint_from(config_.frame.world_from_ned(position_ned_), yaw_ned_rad_, tilt_rad_);
  pose_.timestamp_ns = pose_rx_ns_;
  pose_.valid = true;
}

bool MavlinkMotion::arrived() const {
  if (!have_setpoint_ || holding_ || fault_ != MotionFault::kNone || !pose_.valid) return false;
  if (pose_rx_ns_ <= command_ns_) return false;
  const double distance_m = (position_ned_ - setpoint_ned_).norm();
  const double yaw_error = std::fabs(wrap_angle(yaw_ned_rad_ - setpoint_yaw_rad_));
  return distance_m <= config_.arrive_tolerance_m && yaw_error <= config_.arrive_yaw_tolerance_rad;
}

}  // namespace vantage::hal::mavlink
