#include "hal/mavlink/messages.hpp"

#include "hal/mavlink/wire.hpp"

namespace vantage::hal::mavlink {
namespace {

constexpr MessageSpec kSpecs[] = {
    {kHeartbeatId, 50, 9, 9, "HEARTBEAT"},
    {kAttitudeId, 39, 28, 28, "ATTITUDE"},
    {kLocalPositionNedId, 185, 28, 28, "LOCAL_POSITION_NED"},
    {kCommandLongId, 152, 33, 33, "COMMAND_LONG"},
    {kCommandAckId, 143, 3, 10, "COMMAND_ACK"},
    {kSetPositionTargetLocalNedId, 143, 53, 53, "SET_POSITION_TARGET_LOCAL_NED"},
    {kPositionTargetLocalNedId, 140, 51, 51, "POSITION_TARGET_LOCAL_NED"},
    {kOdometryId, 91, 230, 233, "ODOMETRY"},
};

// The twelve floats shared by SET_POSITION_TARGET_LOCAL_NED and POSITION_TARGET_LOCAL_NED, at offset 4.
template <typename M>
void put_target_floats(const M& m, std::uint8_t* out) {
  const float values[] = {m.x, m.y, m.z, m.vx, m.vy, m.vz, m.afx, m.afy, m.afz, m.yaw, m.yaw_rate};
  for (std::size_t i = 0; i < 11; ++i) put_f32(out + 4 + 4 * i, values[i]);
}
template <typename M>
void get_target_floats(const std::uint8_t* in, M* m) {
  float* fields[] = {&m->x, &m->y, &m->z, &m->vx, &m->vy, &m->vz, &m->afx, &m->afy, &m->afz, &m->yaw, &m->yaw_rate};
  for (std::size_t i = 0; i < 11; ++i) *fields[i] = get_f32(in + 4 + 4 * i);
}

}  // namespace

const MessageSpec* find_message_spec(std::uint32_t id) {
  for (const MessageSpec& spec : kSpecs) {
    if (spec.id == id) return &spec;
  }
  return nullptr;
}

std::size_t encode(const Heartbeat& m, std::uint8_t* out) {
  put_u32(out + 0, m.custom_mode);
  put_u8(out + 4, m.type);
  put_u8(out + 5, m.autopilot);
  put_u8(out + 6, m.base_mode);
  put_u8(out + 7, m.system_status);
  put_u8(out + 8, m.mavlink_version);
  return 9;
}
void decode(const std::uint8_t* in, Heartbeat* m) {
  m->custom_mode = get_u32(in + 0);
  m->type = get_u8(in + 4);
  m->autopilot = get_u8(in + 5);
  m->base_mode = get_u8(in + 6);
  m->system_status = get_u8(in + 7);
  m->mavlink_version = get_u8(in + 8);
}

std::size_t encode(const SetPositionTargetLocalNed& m, std::uint8_t* out) {
  put_u32(out + 0, m.time_boot_ms);
  put_target_floats(m, out);
  put_u16(out + 48, m.type_mask);
  put_u8(out + 50, m.target_system);
  put_u8(out + 51, m.target_component);
  put_u8(out + 52, m.coordinate_frame);
  return 53;
}
void decode(const std::uint8_t* in, SetPositionTargetLocalNed* m) {
  m->time_boot_ms = get_u32(in + 0);
  get_target_floats(in, m);
  m->type_mask = get_u16(in + 48);
  m->target_system = get_u8(in + 50);
  m->target_component = get_u8(in + 51);
  m->coordinate_frame = get_u8(in + 52);
}

std::size_t encode(const PositionTargetLocalNed& m, std::uint8_t* out) {
  put_u32(out + 0, m.time_boot_ms);
  put_target_floats(m, out);
  put_u16(out + 48, m.type_mask);
  put_u8(out + 50, m.coordinate_frame);
  return 51;
}
void decode(const std::uint8_t* in, PositionTargetLocalNed* m) {
  m->time_boot_ms = get_u32(in + 0);
  get_target_floats(in, m);
  m->type_mask = get_u16(in + 48);
  m->coordinate_frame = get_u8(in + 50);
}

std::size_t encode(const LocalPositionNed& m, std::uint8_t* out) {
  put_u32(out + 0, m.time_boot_ms);
  const float values[] = {m.x, m.y, m.z, m.vx, m.vy, m.vz};
  for (std::size_t i = 0; i < 6; ++i) put_f32(out + 4 + 4 * i, values[i]);
  return 28;
}
void decode(const std::uint8_t* in, LocalPositionNed* m) {
  m->time_boot_ms = get_u32(in + 0);
  float* fields[] = {&m->x, &m->y, &m->z, &m->vx, &m->vy, &m->vz};
  for (std::size_t i = 0; i < 6; ++i) *fields[i] = get_f32(in + 4 + 4 * i);
}

std::size_t encode(const Attitude& m, std::uint8_t* out) {
  put_u32(out + 0, m.time_boot_ms);
  const float values[] = {m.roll, m.pitch, m.yaw, m.rollspeed, m.pitchspeed, m.yawspeed};
  for (std::size_t i = 0; i < 6; ++i) put_f32(out + 4 + 4 * i, values[i]);
  return 28;
}
void decode(const std::uint8_t* in, Attitude* m) {
  m->time_boot_ms = get_u32(in + 0);
  float* fields[] = {&m->roll, &m->pitch, &m->yaw, &m->rollspeed, &m->pitchspeed, &m->yawspeed};
  for (std::size_t i = 0; i < 6; ++i) *fields[i] = get_f32(in + 4 + 4 * i);
}

// ODOMETRY: time_usec(8) x y z q[4] vx vy vz rollspeed pitchspeed yawspeed pose_covariance[21]
// velocity_covariance[21] (floats from 8), frame_id(228) child_frame_id(229); extensions reset_counter(230)
// estimator_type(231) quality(232).
std::size_t encode(const Odometry& m, std::uint8_t* out) {
  put_u64(out + 0, m.time_usec);
  std::size_t offset = 8;
  const float head[] = {m.x, m.y, m.z, m.q[0], m.q[1], m.q[2], m.q[3], m.vx, m.vy, m.vz,
                        m.rollspeed, m.pitchspeed, m.yawspeed};
  for (float v : head) { put_f32(out + offset, v); offset += 4; }
  for (float v : m.pose_covariance) { put_f32(out + offset, v); offset += 4; }
  for (float v : m.velocity_covariance) { put_f32(out + offset, v); offset += 4; }
  put_u8(out + 228, m.frame_id);
  put_u8(out + 229, m.child_frame_id);
  put_u8(out + 230, m.reset_counter);
  put_u8(out + 231, m.estimator_type);
  put_u8(out + 232, static_cast<std::uint8_t>(m.quality));
  return 233;
}
void decode(const std::uint8_t* in, Odometry* m) {
  m->time_usec = get_u64(in + 0);
  std::size_t offset = 8;
  float* head[] = {&m->x, &m->y, &m->z, &m->q[0], &m->q[1], &m->q[2], &m->q[3], &m->vx, &m->vy, &m->vz,
                   &m->rollspeed, &m->pitchspeed, &m->yawspeed};
  for (float* f : head) { *f = get_f32(in + offset); offset += 4; }
  for (float& v : m->pose_covariance) { v = get_f32(in + offset); offset += 4; }
  for (float& v : m->velocity_covariance) { v = get_f32(in + offset); offset += 4; }
  m->frame_id = get_u8(in + 228);
  m->child_frame_id = get_u8(in + 229);
  m->reset_counter = get_u8(in + 230);
  m->estimator_type = get_u8(in + 231);
  m->quality = static_cast<std::int8_t>(get_u8(in + 232));
}

std::size_t encode(const CommandLong& m, std::uint8_t* out) {
  for (std::size_t i = 0; i < 7; ++i) put_f32(out + 4 * i, m.param[i]);
  put_u16(out + 28, m.command);
  put_u8(out + 30, m.target_system);
  put_u8(out + 31, m.target_component);
  put_u8(out + 32, m.confirmation);
  return 33;
}
void decode(const std::uint8_t* in, CommandLong* m) {
  for (std::size_t i = 0; i < 7; ++i) m->param[i] = get_f32(in + 4 * i);
  m->command = get_u16(in + 28);
  m->target_system = get_u8(in + 30);
  m->target_component = get_u8(in + 31);
  m->confirmation = get_u8(in + 32);
}

std::size_t encode(const CommandAck& m, std::uint8_t* out) {
  put_u16(out + 0, m.command);
  put_u8(out + 2, m.result);
  put_u8(out + 3, m.progress);
  put_u32(out + 4, static_cast<std::uint32_t>(m.result_param2));
  put_u8(out + 8, m.target_system);
  put_u8(out + 9, m.target_component);
  return 10;
}
void decode(const std::uint8_t* in, CommandAck* m) {
  m->command = get_u16(in + 0);
  m->result = get_u8(in + 2);
  m->progress = get_u8(in + 3);
  m->result_param2 = static_cast<std::int32_t>(get_u32(in + 4));
  m->target_system = get_u8(in + 8);
  m->target_component = get_u8(in + 9);
}

}  // namespace vantage::hal::mavlink
