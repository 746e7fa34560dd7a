#!/usr/bin/env node
// A small MAVLink 2 vehicle for vantage's hal/mavlink tests, built on node-mavlink (an implementation
// independent of ours). It binds UDP 127.0.0.1 on a free port and prints "PORT <n>" first, then waits
// for the companion to speak (it replies to the last sender). It sends HEARTBEAT at 1 Hz and its pose
// (LOCAL_POSITION_NED + ATTITUDE, or ODOMETRY) at --rate-hz, flies toward the last
// SET_POSITION_TARGET_LOCAL_NED at --speed-mps, answers COMMAND_LONG with COMMAND_ACK, and prints one JSON
// line per message it received so a test can check what our encoder sent. --silent-after-s T stops all
// sending T seconds after the companion first spoke (link-loss tests). It exits by itself after
// --duration-s. Loopback only.
'use strict';

const dgram = require('dgram');
const { PassThrough } = require('stream');
const {
  MavLinkPacketSplitter, MavLinkPacketParser, MavLinkProtocolV2, MavLinkPacketSignature,
  minimal, common,
} = require('node-mavlink');

function parse_args(argv) {
  const args = {
    duration_s: 20, rate_hz: 20, speed_mps: 2, yaw_rate_rad_s: Math.PI, start_ned: [0, 0, -2],
    key_hex: '', silent_after_s: -1, bad_frames: false, odometry: false, link_id: 1, ack_result: 0,
  };
  for (let i = 2; i < argv.length; i++) {
    const flag = argv[i];
    const value = argv[i + 1];
    switch (flag) {
      case '--duration-s': args.duration_s = Number(value); i++; break;
      case '--rate-hz': args.rate_hz = Number(value); i++; break;
      case '--speed-mps': args.speed_mps = Number(value); i++; break;
      case '--start-ned': args.start_ned = value.split(',').map(Number); i++; break;
      case '--key-hex': args.key_hex = value; i++; break;
      case '--silent-after-s': args.silent_after_s = Number(value); i++; break;
      case '--ack-result': args.ack_result = Number(value); i++; break;
      case '--bad-frames': args.bad_frames = true; break;
      case '--odometry': args.odometry = true; break;
      default:
        console.error(`peer: unknown argument ${flag}`);
        process.exit(2);
    }
  }
  if (!(args.duration_s > 0) || !(args.rate_hz > 0) || args.start_ned.length !== 3 ||
      args.start_ned.some(v => !Number.isFinite(v))) {
    console.error('peer: bad --duration-s, --rate-hz or --start-ned');
    process.exit(2);
  }
  if (args.key_hex && !/^[0-9a-fA-F]{64}$/.test(args.key_hex)) {
    console.error('peer: --key-hex needs 64 hex digits (a 32-byte MAVLink signing key)');
    process.exit(2);
  }
  return args;
}

const args = parse_args(process.argv);
const key = args.key_hex ? Buffer.from(args.key_hex, 'hex') : null;
const SYSID = 1;
const COMPID = 1;  // MAV_COMP_ID_AUTOPILOT1
const start_ms = Date.now();

const state = {
  pos: args.start_ned.slice(),
  yaw: 0,
  target: args.start_ned.slice(),
  target_yaw: 0,
  seq: 0,
  last_sign_ts: 0,
};
let remote = null;  // the companion, learnt from the first datagram (the companion speaks first)
let first_contact_ms = -1;  // --silent-after-s counts from here

function emit(event) {
  process.stdout.write(JSON.stringify(event) + '\n');
}

// Outgoing: serialize with node-mavlink's MAVLink 2 protocol; sign with a strictly increasing timestamp
// (node-mavlink's own sign() uses Date.now(), which repeats within a millisecond).
function frame(message) {
  const flags = key ? MavLinkProtocolV2.IFLAG_SIGNED : 0;
  const protocol = new MavLinkProtocolV2(SYSID, COMPID, flags);
  const unsigned = protocol.serialize(message, state.seq);
  state.seq = (state.seq + 1) & 255;
  if (!key) return unsigned;
  const signed = Buffer.concat([unsigned, Buffer.alloc(MavLinkPacketSignature.SIGNATURE_LENGTH)]);
  const signer = new MavLinkPacketSignature(signed);
  const now_10us = (Date.now() - MavLinkProtocolV2.SIGNATURE_START_TIME) * 100;
  state.last_sign_ts = Math.max(state.last_sign_ts + 1, now_10us);
  signer.linkId = args.link_id;
  signer.timestamp = state.last_sign_ts;
  signer.signature = signer.calculate(key);
  return signed;
}

const socket = dgram.createSocket('udp4');

function send_buffer(buffer) {
  if (!remote) return;
  socket.send(buffer, remote.port, remote.address);
}

function send(message) {
  send_buffer(frame(message));
}

function heartbeat() {
  const hb = new minimal.Heartbeat();
  hb.type = 2;          // MAV_TYPE_QUADROTOR
  hb.autopilot = 12;    // MAV_AUTOPILOT_PX4
  hb.baseMode = 1 | 4 | 128;  // custom mode, guided, armed
  hb.customMode = 0;
  hb.systemStatus = 4;  // MAV_STATE_ACTIVE
  hb.mavlinkVersion = 3;
  return hb;
}

function time_boot_ms() {
  return (Date.now() - start_ms) >>> 0;
}

function send_pose() {
  if (args.odometry) {
    const odo = new common.Odometry();
    odo.timeUsec = BigInt(Date.now() - start_ms) * 1000n;
    odo.x = state.pos[0]; odo.y = state.pos[1]; odo.z = state.pos[2];
    // Body (FRD) to local NED: a rotation about down by yaw. q = [w, x, y, z].
    odo.q = [Math.cos(state.yaw / 2), 0, 0, Math.sin(state.yaw / 2)];
    odo.vx = 0; odo.vy = 0; odo.vz = 0;
    odo.rollspeed = 0; odo.pitchspeed = 0; odo.yawspeed = 0;
    odo.poseCovariance = new Array(21).fill(0);
    odo.velocityCovariance = new Array(21).fill(0);
    odo.frameId = 1;       // MAV_FRAME_LOCAL_NED
    odo.childFrameId = 12; // MAV_FRAME_BODY_FRD
    odo.resetCounter = 0; odo.estimatorType = 0; odo.quality = 100;
    send(odo);
    return;
  }
  const lp = new common.LocalPositionNed();
  lp.timeBootMs = time_boot_ms();
  lp.x = state.pos[0]; lp.y = state.pos[1]; lp.z = state.pos[2];
  lp.vx = 0; lp.vy = 0; lp.vz = 0;
  send(lp);
  const att = new common.Attitude();
  att.timeBootMs = time_boot_ms();
  att.roll = 0; att.pitch = 0; att.yaw = state.yaw;
  att.rollspeed = 0; att.pitchspeed = 0; att.yawspeed = 0;
  send(att);
}

// Malformed traffic between good frames: garbage, a truncated frame, a frame with a wrong CRC, and a
// frame with a wrong length byte. The companion must drop these and keep every good frame.
function send_bad_frames() {
  send_buffer(Buffer.from([0x00, 0xfd, 0x13, 0x37, 0xfe, 0x01, 0xfd]));
  const good = frame(heartbeat());
  send_buffer(good.subarray(0, Math.floor(good.length / 2)));
  const bad_crc = Buffer.from(good);
  bad_crc[bad_crc.length - (key ? 14 : 1)] ^= 0x5a;
  send_buffer(bad_crc);
  const bad_len = Buffer.from(good);
  bad_len[1] = 200;
  send_buffer(bad_len);
}

function step(dt_s) {
  const d = [0, 1, 2].map(i => state.target[i] - state.pos[i]);
  const dist = Math.hypot(d[0], d[1], d[2]);
  const max_step = args.speed_mps * dt_s;
  if (dist <= max_step) {
    state.pos = state.target.slice();
  } else {
    for (let i = 0; i < 3; i++) state.pos[i] += d[i] / dist * max_step;
  }
  let dyaw = state.target_yaw - state.yaw;
  dyaw = Math.atan2(Math.sin(dyaw), Math.cos(dyaw));
  const max_yaw = args.yaw_rate_rad_s * dt_s;
  state.yaw += Math.max(-max_yaw, Math.min(max_yaw, dyaw));
  state.yaw = Math.atan2(Math.sin(state.yaw), Math.cos(state.yaw));
}

// Incoming: node-mavlink's splitter checks framing and CRC; we decode the messages we know.
const input = new PassThrough();
const splitter = new MavLinkPacketSplitter();
const reader = input.pipe(splitter).pipe(new MavLinkPacketParser());
const REGISTRY = { ...minimal.REGISTRY, ...common.REGISTRY };

reader.on('data', packet => {
  const clazz = REGISTRY[packet.header.msgid];
  if (!clazz) {
    emit({ ev: 'rx_unknown', msgid: packet.header.msgid });
    return;
  }
  const signed = !!packet.signature;
  if (key) {
    if (!signed || !packet.signature.matches(key)) {
      emit({ ev: 'rx_bad_signature', msg: clazz.MSG_NAME });
      return;
    }
  }
  const data = packet.protocol.data(packet.payload, clazz);
  const base = {
    ev: 'rx', msg: clazz.MSG_NAME, sysid: packet.header.sysid, compid: packet.header.compid,
    v2: packet.protocol instanceof MavLinkProtocolV2, signed,
  };
  switch (clazz.MSG_NAME) {
    case 'HEARTBEAT':
      emit({ ...base, type: data.type, autopilot: data.autopilot, mavlink_version: data.mavlinkVersion });
      break;
    case 'SET_POSITION_TARGET_LOCAL_NED': {
      emit({ ...base, x: data.x, y: data.y, z: data.z, yaw: data.yaw, type_mask: data.typeMask,
             frame: data.coordinateFrame, target_system: data.targetSystem,
             target_component: data.targetComponent });
      const mask = data.typeMask;
      if ((mask & 0x7) === 0 && data.coordinateFrame === 1) state.target = [data.x, data.y, data.z];
      if ((mask & 0x400) === 0) state.target_yaw = data.yaw;
      break;
    }
    case 'COMMAND_LONG': {
      emit({ ...base, command: data.command, param1: data._param1, param2: data._param2,
             target_system: data.targetSystem, target_component: data.targetComponent });
      const ack = new common.CommandAck();
      ack.command = data.command;
      ack.result = args.ack_result;
      ack.progress = 0; ack.resultParam2 = 0;
      ack.targetSystem = packet.header.sysid;
      ack.targetComponent = packet.header.compid;
      send(ack);
      break;
    }
    default:
      emit(base);
  }
});

socket.on('message', (buffer, rinfo) => {
  if (rinfo.address !== '127.0.0.1') return;  // loopback only
  remote = { address: rinfo.address, port: rinfo.port };
  if (first_contact_ms < 0) first_contact_ms = Date.now();
  input.write(buffer);
});

socket.bind(0, '127.0.0.1', () => {
  process.stdout.write(`PORT ${socket.address().port}\n`);
  const period_ms = 1000 / args.rate_hz;
  let last_ms = Date.now();
  let last_heartbeat_ms = 0;
  const timer = setInterval(() => {
    const now_ms = Date.now();
    step((now_ms - last_ms) / 1000);
    last_ms = now_ms;
    const silent = args.silent_after_s >= 0 && first_contact_ms >= 0 &&
                   now_ms - first_contact_ms >= args.silent_after_s * 1000;
    if (!remote || silent) return;
    if (now_ms - last_heartbeat_ms >= 1000) {
      send(heartbeat());
      last_heartbeat_ms = now_ms;
      if (args.bad_frames) send_bad_frames();
    }
    send_pose();
  }, period_ms);
  setTimeout(() => {
    clearInterval(timer);
    emit({ ev: 'exit', invalid: splitter.invalidPackages, unknown: splitter.unknownPackagesCount,
           pos: state.pos, yaw: state.yaw });
    socket.close();
  }, args.duration_s * 1000);
});
