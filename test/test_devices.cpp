// Device-protocol library tests: CRC16, NDI Aurora commands / replies / BX stream, flow-sensor lines
// and the valve-board protocol. ROS-free; no hardware, no I/O.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hydrojet_control/devices/aurora_protocol.h"
#include "hydrojet_control/devices/crc16.h"
#include "hydrojet_control/devices/line_protocols.h"

using namespace hydrojet::devices;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A valid handle pose: rotation `angle` [rad] about z, position t [m].
HandlePose valid_pose(uint8_t handle, double angle, double x, double y, double z, uint32_t frame) {
  HandlePose h;
  h.handle = handle;
  h.status = HandlePose::kValid;
  h.q[0] = std::cos(angle / 2);
  h.q[1] = 0.0;
  h.q[2] = 0.0;
  h.q[3] = std::sin(angle / 2);
  h.t[0] = x;
  h.t[1] = y;
  h.t[2] = z;
  h.rms_m = 0.4e-3;
  h.port_status = 0x31;  // occupied | initialized | enabled
  h.frame = frame;
  return h;
}

HandlePose missing_pose(uint8_t handle, uint32_t frame) {
  HandlePose h;
  h.handle = handle;
  h.status = HandlePose::kMissing;
  for (double& v : h.q) v = kNaN;
  for (double& v : h.t) v = kNaN;
  h.rms_m = kNaN;
  h.port_status = 0x31;
  h.frame = frame;
  return h;
}

/// Two-handle frame: tip (0x0A) valid, base (0x0B) missing.
BxFrame two_handle_frame(uint32_t frame_no, double phase = 0.3) {
  BxFrame f;
  f.handles.push_back(valid_pose(0x0A, phase, 0.0125, -0.020, -0.150, frame_no));
  f.handles.push_back(missing_pose(0x0B, frame_no));
  f.system_status = 0x0000;
  return f;
}

std::vector<uint8_t> bytes(const std::string& s) { return std::vector<uint8_t>(s.begin(), s.end()); }

void append(std::vector<uint8_t>* dst, const std::vector<uint8_t>& src) {
  dst->insert(dst->end(), src.begin(), src.end());
}

std::vector<BxFrame> drain(BxParser* p) {
  std::vector<BxFrame> out;
  BxFrame f;
  while (p->next(&f)) out.push_back(f);
  return out;
}

/// Float32 round trip of a value in [mm] back to [m]: the precision the wire allows.
double f32_mm(double m) { return static_cast<double>(static_cast<float>(m * 1e3)) * 1e-3; }

void expect_tip(const BxFrame& f, uint32_t frame_no, double phase = 0.3) {
  ASSERT_EQ(f.handles.size(), 2u);
  const HandlePose& tip = f.handles[0];
  EXPECT_EQ(tip.handle, 0x0A);
  EXPECT_EQ(tip.status, HandlePose::kValid);
  EXPECT_NEAR(tip.q[0], std::cos(phase / 2), 1e-6);
  EXPECT_NEAR(tip.q[3], std::sin(phase / 2), 1e-6);
  EXPECT_EQ(tip.frame, frame_no);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// CRC16
// ---------------------------------------------------------------------------------------------

TEST(Crc16, KnownVectors) {
  EXPECT_EQ(crc16_arc(std::string("INIT:")), 0xE3A5);
  EXPECT_EQ(crc16_arc(std::string("RESET")), 0xBE6F);
  EXPECT_EQ(crc16_arc(std::string("123456789")), 0xBB3D);  // CRC-16/ARC check value
  EXPECT_EQ(crc16_arc(std::string("OKAY")), 0xA896);
  EXPECT_EQ(crc16_arc(nullptr, 0), 0x0000);
  EXPECT_EQ(crc16_hex(0xE3A5), "E3A5");
  EXPECT_EQ(crc16_hex(0x00F1), "00F1");
}

TEST(Crc16, PointerAndStringOverloadsAgree) {
  const std::string s("\xC4\xA5\x10\x00", 4);
  EXPECT_EQ(crc16_arc(s), crc16_arc(reinterpret_cast<const uint8_t*>(s.data()), s.size()));
}

// ---------------------------------------------------------------------------------------------
// ASCII commands and replies
// ---------------------------------------------------------------------------------------------

TEST(AuroraAscii, FormatCommand) {
  EXPECT_EQ(format_command("INIT", ""), "INIT:E3A5\r");
  const std::string comm = format_command("COMM", "50000");
  EXPECT_EQ(comm.substr(0, 10), "COMM:50000");
  EXPECT_EQ(comm.substr(10), crc16_hex(crc16_arc(std::string("COMM:50000"))) + "\r");
  EXPECT_EQ(format_command("PENA", "0AD").substr(0, 8), "PENA:0AD");
  EXPECT_THROW(format_command("", "x"), std::invalid_argument);
  EXPECT_THROW(format_command("init", ""), std::invalid_argument);
  EXPECT_THROW(format_command("PENA", "0A\rD"), std::invalid_argument);
  EXPECT_THROW(format_command("PENA", "0A:D"), std::invalid_argument);
}

TEST(AuroraAscii, OkayAndResetReplies) {
  AsciiReply r = parse_ascii_reply("OKAYA896");
  EXPECT_TRUE(r.ok);
  EXPECT_TRUE(r.crc_ok);
  EXPECT_EQ(r.text, "OKAY");
  EXPECT_TRUE(r.error.empty());
  r = parse_ascii_reply("RESETBE6F");
  EXPECT_TRUE(r.ok);
  EXPECT_EQ(r.text, "RESET");
  r = parse_ascii_reply("OKAYa896");  // lower-case hex accepted
  EXPECT_TRUE(r.ok);
}

TEST(AuroraAscii, CrcErrorsDetected) {
  AsciiReply r = parse_ascii_reply("OKAYA897");
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.crc_ok);
  EXPECT_NE(r.error.find("CRC"), std::string::npos);
  r = parse_ascii_reply("OKBYA896");  // corrupted text, original CRC
  EXPECT_FALSE(r.crc_ok);
  r = parse_ascii_reply("OKAYZZZZ");
  EXPECT_FALSE(r.crc_ok);
  EXPECT_FALSE(r.ok);
  r = parse_ascii_reply("OK");
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.crc_ok);
  EXPECT_FALSE(parse_ascii_reply("").ok);
}

TEST(AuroraAscii, ErrorReplyDecoded) {
  const std::string text = "ERROR0C";
  AsciiReply r = parse_ascii_reply(text + crc16_hex(crc16_arc(text)));
  EXPECT_TRUE(r.crc_ok);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.text, "ERROR0C");
  EXPECT_EQ(r.error, describe_error("0C"));
  EXPECT_EQ(r.error.compare(0, 9, "ERROR0C: "), 0);
}

TEST(AuroraAscii, DescribeError) {
  EXPECT_EQ(describe_error("ERROR01"), "ERROR01: invalid command");
  EXPECT_EQ(describe_error("02"), "ERROR02: command too long");
  EXPECT_EQ(describe_error("03"), "ERROR03: command too short");
  EXPECT_EQ(describe_error("04"), "ERROR04: invalid CRC in command");
  EXPECT_EQ(describe_error("05"), "ERROR05: time-out on command execution");
  for (const char* c : {"0C", "0D", "0E", "0c"}) {
    const std::string d = describe_error(c);
    EXPECT_EQ(d.find("unknown"), std::string::npos) << d;
    EXPECT_EQ(d.compare(0, 5, "ERROR"), 0) << d;
  }
  EXPECT_NE(describe_error("0D").find("port handle"), std::string::npos);
  EXPECT_NE(describe_error("0E").find("port handle"), std::string::npos);
  EXPECT_EQ(describe_error("ERRORF7"), "ERRORF7: unknown");
  EXPECT_EQ(describe_error("ERROR1"), "malformed error code 'ERROR1'");
  EXPECT_EQ(describe_error("XY"), "malformed error code 'XY'");
}

TEST(AuroraAscii, ParsePhsr) {
  const auto v = parse_phsr("020A0010B031");
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v[0].first, 0x0A);
  EXPECT_EQ(v[0].second, 0x001);
  EXPECT_EQ(v[1].first, 0x0B);
  EXPECT_EQ(v[1].second, 0x031);
  EXPECT_TRUE(parse_phsr("00").empty());
  EXPECT_THROW(parse_phsr("020A001"), std::invalid_argument);       // too short
  EXPECT_THROW(parse_phsr("010A0010B001"), std::invalid_argument);  // too long
  EXPECT_THROW(parse_phsr("010G001"), std::invalid_argument);       // not hex
  EXPECT_THROW(parse_phsr(""), std::invalid_argument);
  std::vector<std::pair<uint8_t, uint16_t>> out;
  std::string err;
  EXPECT_FALSE(parse_phsr("01", &out, &err));
  EXPECT_FALSE(err.empty());
}

// ---------------------------------------------------------------------------------------------
// BX encode / decode
// ---------------------------------------------------------------------------------------------

TEST(AuroraBx, WireLayout) {
  const std::vector<uint8_t> w = encode_bx(two_handle_frame(1234));
  // body: count 1 + tip (2 + 32 + 8) + base (2 + 8) + system status 2 = 55 bytes
  ASSERT_EQ(w.size(), kBxHeaderSize + 55 + 2);
  EXPECT_EQ(w[0], 0xC4);
  EXPECT_EQ(w[1], 0xA5);
  EXPECT_EQ(w[2] | (w[3] << 8), 55);
  EXPECT_EQ(w[4] | (w[5] << 8), crc16_arc(w.data(), 4));
  EXPECT_EQ(w[6], 2);     // handle count
  EXPECT_EQ(w[7], 0x0A);  // handle
  EXPECT_EQ(w[8], kBxHandleValid);
  float tx_mm;
  std::memcpy(&tx_mm, &w[9 + 16], 4);  // after q0..qz
  EXPECT_FLOAT_EQ(tx_mm, 12.5f);       // 0.0125 m on the wire in mm
  EXPECT_EQ(w[9 + 32 + 8], 0x0B);
  EXPECT_EQ(w[9 + 32 + 8 + 1], kBxHandleMissing);
  const size_t body_len = 55;
  EXPECT_EQ(w[6 + body_len] | (w[7 + body_len] << 8), crc16_arc(&w[6], body_len));
}

TEST(AuroraBx, RoundTripTwoHandlesMmToM) {
  const BxFrame in = two_handle_frame(4242);
  BxParser p;
  p.feed(encode_bx(in).data(), encode_bx(in).size());
  BxFrame out;
  ASSERT_TRUE(p.next(&out));
  EXPECT_FALSE(p.next(&out));
  ASSERT_EQ(out.handles.size(), 2u);
  const HandlePose& tip = out.handles[0];
  EXPECT_EQ(tip.handle, 0x0A);
  EXPECT_EQ(tip.status, HandlePose::kValid);
  EXPECT_TRUE(tip.has_transform());
  for (int k = 0; k < 4; ++k) EXPECT_NEAR(tip.q[k], in.handles[0].q[k], 1e-6);
  for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(tip.t[k], f32_mm(in.handles[0].t[k]));
  EXPECT_NEAR(tip.t[0], 0.0125, 1e-9);  // [m]
  EXPECT_NEAR(tip.t[2], -0.150, 1e-8);
  EXPECT_NEAR(tip.rms_m, 0.4e-3, 1e-9);
  EXPECT_EQ(tip.port_status, 0x31u);
  EXPECT_EQ(tip.frame, 4242u);
  const double qn = std::sqrt(tip.q[0] * tip.q[0] + tip.q[1] * tip.q[1] + tip.q[2] * tip.q[2] + tip.q[3] * tip.q[3]);
  EXPECT_NEAR(qn, 1.0, 1e-12);
  const HandlePose& base = out.handles[1];
  EXPECT_EQ(base.handle, 0x0B);
  EXPECT_EQ(base.status, HandlePose::kMissing);
  EXPECT_FALSE(base.has_transform());
  EXPECT_TRUE(std::isnan(base.t[0]));
  EXPECT_EQ(base.frame, 4242u);
  EXPECT_TRUE(out.has_system_status);
  ASSERT_NE(out.find(0x0B), nullptr);
  EXPECT_EQ(out.find(0x0C), nullptr);
  EXPECT_EQ(p.frames(), 1u);
  EXPECT_EQ(p.crc_errors(), 0u);
  EXPECT_EQ(p.garbage_bytes(), 0u);
}

TEST(AuroraBx, BodyWithoutSystemStatusAndDisabledHandle) {
  BxFrame in = two_handle_frame(7);
  HandlePose dis;
  dis.handle = 0x0C;
  dis.status = HandlePose::kDisabled;
  in.handles.push_back(dis);
  in.has_system_status = false;
  const auto w = encode_bx(in);
  EXPECT_EQ(w[2] | (w[3] << 8), 55 - 2 + 2);  // no system status, + disabled entry (2 bytes)
  BxParser p;
  p.feed(w.data(), w.size());
  BxFrame out;
  ASSERT_TRUE(p.next(&out));
  EXPECT_FALSE(out.has_system_status);
  ASSERT_EQ(out.handles.size(), 3u);
  EXPECT_EQ(out.handles[2].status, HandlePose::kDisabled);
  EXPECT_EQ(out.handles[2].handle, 0x0C);
}

TEST(AuroraBx, OutOfVolumeBitGivesOutOfVolume) {
  for (uint32_t bit : {kPortOutOfVolume, kPortPartiallyOutOfVolume, kPortBit8}) {
    BxFrame in = two_handle_frame(9);
    in.handles[0].port_status |= bit;  // valid transform, flagged out of volume
    in.handles[1].port_status |= bit;  // missing, flagged out of volume
    const auto w = encode_bx(in);
    BxParser p;
    p.feed(w.data(), w.size());
    BxFrame out;
    ASSERT_TRUE(p.next(&out)) << bit;
    EXPECT_EQ(out.handles[0].status, HandlePose::kOutOfVolume) << bit;
    EXPECT_TRUE(out.handles[0].has_transform());
    EXPECT_EQ(out.handles[1].status, HandlePose::kOutOfVolume) << bit;
    EXPECT_FALSE(out.handles[1].has_transform());
  }
  // A narrower mask ignores the other bits.
  BxFrame in = two_handle_frame(9);
  in.handles[0].port_status |= 0x80;
  BxParser narrow(kPortOutOfVolume);
  const auto w = encode_bx(in);
  narrow.feed(w.data(), w.size());
  BxFrame out;
  ASSERT_TRUE(narrow.next(&out));
  EXPECT_EQ(out.handles[0].status, HandlePose::kValid);
  // The encoder sets an out-of-volume bit for kOutOfVolume if none is set.
  in = two_handle_frame(9);
  in.handles[0].status = HandlePose::kOutOfVolume;
  BxParser p;
  const auto w2 = encode_bx(in);
  p.feed(w2.data(), w2.size());
  ASSERT_TRUE(p.next(&out));
  EXPECT_EQ(out.handles[0].status, HandlePose::kOutOfVolume);
}

TEST(AuroraBx, EncoderValidates) {
  BxFrame f = two_handle_frame(1);
  f.handles[0].t[1] = kNaN;
  EXPECT_THROW(encode_bx(f), std::invalid_argument);
  BxFrame big;
  big.handles.resize(256, missing_pose(1, 0));
  EXPECT_THROW(encode_bx(big), std::invalid_argument);
}

TEST(AuroraBx, DecodeRejectsInconsistentBodies) {
  const auto w = encode_bx(two_handle_frame(3));
  std::vector<uint8_t> body(w.begin() + 6, w.end() - 2);
  BxFrame out;
  std::string err;
  EXPECT_TRUE(decode_bx_body(body.data(), body.size(), kDefaultOutOfVolumeMask, &out, &err));
  // Trailing byte count other than 0 or 2.
  std::vector<uint8_t> b2 = body;
  b2.push_back(0);
  EXPECT_FALSE(decode_bx_body(b2.data(), b2.size(), kDefaultOutOfVolumeMask, &out, &err));
  // Body cut inside a handle.
  EXPECT_FALSE(decode_bx_body(body.data(), 20, kDefaultOutOfVolumeMask, &out, &err));
  // Unknown status byte.
  b2 = body;
  b2[2] = 0x08;
  EXPECT_FALSE(decode_bx_body(b2.data(), b2.size(), kDefaultOutOfVolumeMask, &out, &err));
  EXPECT_NE(err.find("status"), std::string::npos);
  // Non-unit quaternion.
  b2 = body;
  const float two = 2.0f;
  std::memcpy(&b2[3], &two, 4);
  EXPECT_FALSE(decode_bx_body(b2.data(), b2.size(), kDefaultOutOfVolumeMask, &out, &err));
  // NaN translation.
  b2 = body;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&b2[3 + 16], &nan, 4);
  EXPECT_FALSE(decode_bx_body(b2.data(), b2.size(), kDefaultOutOfVolumeMask, &out, &err));
  EXPECT_FALSE(decode_bx_body(body.data(), 0, kDefaultOutOfVolumeMask, &out, &err));
}

// ---------------------------------------------------------------------------------------------
// BX streaming parser
// ---------------------------------------------------------------------------------------------

TEST(BxParser, ByteByByte) {
  std::vector<uint8_t> stream;
  for (uint32_t i = 0; i < 5; ++i) append(&stream, encode_bx(two_handle_frame(100 + i)));
  BxParser p;
  std::vector<BxFrame> got;
  for (uint8_t b : stream) {
    p.feed(&b, 1);
    BxFrame f;
    while (p.next(&f)) got.push_back(f);
  }
  ASSERT_EQ(got.size(), 5u);
  for (uint32_t i = 0; i < 5; ++i) expect_tip(got[i], 100 + i);
  EXPECT_EQ(p.crc_errors(), 0u);
  EXPECT_EQ(p.garbage_bytes(), 0u);
  EXPECT_EQ(p.buffered(), 0u);
}

TEST(BxParser, RandomChunks) {
  std::mt19937 rng(12345);
  std::vector<uint8_t> stream;
  const int n = 200;
  for (int i = 0; i < n; ++i) append(&stream, encode_bx(two_handle_frame(i, 0.01 * i)));
  for (int trial = 0; trial < 20; ++trial) {
    BxParser p;
    std::vector<BxFrame> got;
    size_t pos = 0;
    std::uniform_int_distribution<size_t> chunk(1, 150);
    while (pos < stream.size()) {
      const size_t c = std::min(chunk(rng), stream.size() - pos);
      p.feed(&stream[pos], c);
      pos += c;
      BxFrame f;
      while (p.next(&f)) got.push_back(f);
    }
    ASSERT_EQ(got.size(), static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) expect_tip(got[static_cast<size_t>(i)], i, 0.01 * i);
    EXPECT_EQ(p.frames(), static_cast<uint64_t>(n));
    EXPECT_EQ(p.garbage_bytes(), 0u);
  }
}

TEST(BxParser, GarbageBeforeAndBetweenFrames) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> stream;
  size_t garbage = 0;
  auto add_garbage = [&](size_t n) {
    for (size_t k = 0; k < n; ++k) {
      uint8_t b = static_cast<uint8_t>(byte(rng));
      if (b == 0xC4) b = 0x00;  // count-exact garbage (random C4 A5 is tested below)
      stream.push_back(b);
    }
    garbage += n;
  };
  add_garbage(37);
  const std::vector<uint8_t> err_reply = bytes("ERROR0C" + crc16_hex(crc16_arc(std::string("ERROR0C"))) + "\r");
  for (uint32_t i = 0; i < 10; ++i) {
    append(&stream, encode_bx(two_handle_frame(i)));
    if (i % 3 == 0) {
      append(&stream, err_reply);  // an ASCII reply in the stream is garbage to the BX parser
      garbage += err_reply.size();
    }
    add_garbage(i);
  }
  BxParser p;
  for (size_t pos = 0; pos < stream.size(); pos += 13) p.feed(&stream[pos], std::min<size_t>(13, stream.size() - pos));
  const auto got = drain(&p);
  ASSERT_EQ(got.size(), 10u);
  for (uint32_t i = 0; i < 10; ++i) expect_tip(got[i], i);
  EXPECT_EQ(p.garbage_bytes(), garbage);
  EXPECT_EQ(p.crc_errors(), 0u);
}

TEST(BxParser, FakeStartSequencesInGarbage) {
  std::vector<uint8_t> stream = {0xC4, 0xA5, 0x10, 0x00, 0x12, 0x34,  // header with a bad CRC
                                 0xC4, 0xC4, 0xA5};                   // double C4, then cut
  append(&stream, encode_bx(two_handle_frame(1)));
  stream.push_back(0xC4);  // lone C4 at the end: kept until the next byte decides
  BxParser p;
  p.feed(stream.data(), stream.size());
  auto got = drain(&p);
  ASSERT_EQ(got.size(), 1u);
  expect_tip(got[0], 1);
  EXPECT_GE(p.crc_errors(), 1u);
  EXPECT_EQ(p.buffered(), 1u);
  const auto next = encode_bx(two_handle_frame(2));
  p.feed(next.data(), next.size());
  got = drain(&p);
  ASSERT_EQ(got.size(), 1u);
  expect_tip(got[0], 2);
}

TEST(BxParser, CorruptedBodyByteDropsFrameOnly) {
  const auto f1 = encode_bx(two_handle_frame(1));
  auto f2 = encode_bx(two_handle_frame(2));
  const auto f3 = encode_bx(two_handle_frame(3));
  f2[6 + 20] ^= 0x01;  // one bit of the tip's translation
  std::vector<uint8_t> stream;
  append(&stream, f1);
  append(&stream, f2);
  append(&stream, f3);
  BxParser p;
  p.feed(stream.data(), stream.size());
  const auto got = drain(&p);
  ASSERT_EQ(got.size(), 2u);
  expect_tip(got[0], 1);
  expect_tip(got[1], 3);
  EXPECT_EQ(p.crc_errors(), 1u);
  EXPECT_EQ(p.garbage_bytes(), f2.size());
  EXPECT_EQ(p.frames(), 2u);
}

TEST(BxParser, CorruptedHeaderAndBodyCrcBytes) {
  auto bad_hdr = encode_bx(two_handle_frame(1));
  bad_hdr[4] ^= 0xFF;
  auto bad_crc = encode_bx(two_handle_frame(2));
  bad_crc.back() ^= 0x80;
  auto bad_len = encode_bx(two_handle_frame(3));
  bad_len[2] += 1;  // length no longer matches the header CRC
  std::vector<uint8_t> stream;
  append(&stream, bad_hdr);
  append(&stream, bad_crc);
  append(&stream, bad_len);
  append(&stream, encode_bx(two_handle_frame(4)));
  BxParser p;
  p.feed(stream.data(), stream.size());
  const auto got = drain(&p);
  ASSERT_EQ(got.size(), 1u);
  expect_tip(got[0], 4);
  EXPECT_EQ(p.crc_errors(), 3u);
}

TEST(BxParser, TruncatedFrameFollowedByGoodOne) {
  const auto full = encode_bx(two_handle_frame(1));
  for (size_t cut : {3u, 6u, 7u, 30u, 60u}) {
    std::vector<uint8_t> stream(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(cut));
    append(&stream, encode_bx(two_handle_frame(2)));
    BxParser p;
    p.feed(stream.data(), stream.size());
    const auto got = drain(&p);
    ASSERT_EQ(got.size(), 1u) << "cut " << cut;  // delivered without waiting for more bytes
    expect_tip(got[0], 2);
    EXPECT_EQ(p.buffered(), 0u);
    EXPECT_EQ(p.garbage_bytes(), cut);
  }
}

TEST(BxParser, TruncatedLongFrameFollowedByShortOne) {
  // The truncated frame claims more bytes than the good frame supplies: the parser must notice the
  // complete valid frame inside the pending extent instead of waiting.
  BxFrame big = two_handle_frame(1);
  for (uint8_t h = 0x10; h < 0x18; ++h) big.handles.push_back(valid_pose(h, 0.1, 0.01, 0.0, 0.0, 1));
  const auto long_frame = encode_bx(big);
  BxFrame small;
  small.handles.push_back(valid_pose(0x0A, 0.3, 0.0125, -0.02, -0.15, 2));
  const auto short_frame = encode_bx(small);
  std::vector<uint8_t> stream(long_frame.begin(), long_frame.begin() + 40);
  append(&stream, short_frame);
  ASSERT_LT(stream.size(), long_frame.size());
  BxParser p;
  p.feed(stream.data(), stream.size());
  const auto got = drain(&p);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].handles[0].frame, 2u);
  EXPECT_EQ(p.truncated_frames(), 1u);
}

TEST(BxParser, ImpossibleLengthRejected) {
  std::vector<uint8_t> hdr = {0xC4, 0xA5, 0xFF, 0xFF};  // 65535-byte body: impossible
  const uint16_t c = crc16_arc(hdr.data(), 4);
  hdr.push_back(static_cast<uint8_t>(c & 0xFF));
  hdr.push_back(static_cast<uint8_t>(c >> 8));
  append(&hdr, encode_bx(two_handle_frame(5)));
  BxParser p;
  p.feed(hdr.data(), hdr.size());
  const auto got = drain(&p);
  ASSERT_EQ(got.size(), 1u);
  expect_tip(got[0], 5);
  EXPECT_EQ(p.format_errors(), 1u);
}

TEST(BxParser, ResetDropsPartialFrame) {
  const auto f1 = encode_bx(two_handle_frame(1));
  BxParser p;
  p.feed(f1.data(), 20);
  BxFrame out;
  EXPECT_FALSE(p.next(&out));
  p.reset();
  EXPECT_EQ(p.buffered(), 0u);
  EXPECT_EQ(p.garbage_bytes(), 20u);
  p.feed(f1.data(), f1.size());
  EXPECT_TRUE(p.next(&out));
}

TEST(BxParser, RandomCorruptionNeverEmitsBadFrames) {
  // Fuzz: random bit flips, drops and insertions. Every emitted frame must be one of the originals.
  std::mt19937 rng(99);
  std::vector<uint8_t> stream;
  const int n = 300;
  for (int i = 0; i < n; ++i) append(&stream, encode_bx(two_handle_frame(i, 0.01 * i)));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> noisy;
  for (uint8_t b : stream) {
    const double r = u(rng);
    if (r < 0.0005) continue;                                        // drop
    if (r < 0.001) b ^= static_cast<uint8_t>(1 << (byte(rng) % 8));  // flip
    noisy.push_back(b);
    if (u(rng) < 0.0005) noisy.push_back(static_cast<uint8_t>(byte(rng)));  // insert
  }
  BxParser p;
  for (size_t pos = 0; pos < noisy.size(); pos += 64) p.feed(&noisy[pos], std::min<size_t>(64, noisy.size() - pos));
  const auto got = drain(&p);
  EXPECT_GT(got.size(), static_cast<size_t>(n * 0.8));
  uint32_t last = 0;
  for (const BxFrame& f : got) {
    ASSERT_EQ(f.handles.size(), 2u);
    const uint32_t i = f.handles[0].frame;
    ASSERT_LT(i, static_cast<uint32_t>(n));
    expect_tip(f, i, 0.01 * i);
    EXPECT_TRUE(got.size() == 0 || i >= last);
    last = i;
  }
  EXPECT_EQ(p.frames(), got.size());
}

// ---------------------------------------------------------------------------------------------
// TX reply (hand-built strings, from the layout of the NDI API as ndicapi reads it)
// ---------------------------------------------------------------------------------------------

namespace {

// Handle 0A valid: q = (0.7071, 0, 0.7071, 0) (norm 0.99999, renormalised), t = (12.34, -5.67,
// -150.00) mm, rms 0.3 mm, port status 0x31, frame 0x1F4; handle 0B missing with port status 0x11,
// frame 0x1F4; handle 0C disabled; system status 0x0000.
const std::string kTxNominal =
    "03"
    "0A+07071+00000+07071+00000+001234-000567-015000+03000"
    "00000031"
    "000001F4"
    "\n"
    "0BMISSING"
    "00000011"
    "000001F4"
    "\n"
    "0CDISABLED\n"
    "0000";

}  // namespace

TEST(AuroraTx, NominalReplyInSiUnits) {
  ASSERT_EQ(std::string("+07071+00000+07071+00000+001234-000567-015000+03000").size(), kTxTransformChars);
  BxFrame f;
  std::string err;
  ASSERT_TRUE(parse_tx_reply(kTxNominal, kDefaultOutOfVolumeMask, &f, &err)) << err;
  ASSERT_EQ(f.handles.size(), 3u);
  const HandlePose& a = f.handles[0];
  EXPECT_EQ(a.handle, 0x0A);
  EXPECT_EQ(a.status, HandlePose::kValid);
  const double n = std::sqrt(2 * 0.7071 * 0.7071);
  EXPECT_NEAR(a.q[0], 0.7071 / n, 1e-12);
  EXPECT_NEAR(a.q[2], 0.7071 / n, 1e-12);
  EXPECT_NEAR(a.q[0] * a.q[0] + a.q[2] * a.q[2], 1.0, 1e-12);  // renormalised
  EXPECT_EQ(a.q[1], 0.0);
  EXPECT_NEAR(a.t[0], 0.01234, 1e-12);
  EXPECT_NEAR(a.t[1], -0.00567, 1e-12);
  EXPECT_NEAR(a.t[2], -0.150, 1e-12);
  EXPECT_NEAR(a.rms_m, 0.3e-3, 1e-12);
  EXPECT_EQ(a.port_status, 0x31u);
  EXPECT_EQ(a.frame, 500u);
  const HandlePose& b = f.handles[1];
  EXPECT_EQ(b.handle, 0x0B);
  EXPECT_EQ(b.status, HandlePose::kMissing);
  EXPECT_FALSE(b.has_transform());
  EXPECT_EQ(b.port_status, 0x11u);  // missing handles carry port status and frame number too
  EXPECT_EQ(b.frame, 500u);
  EXPECT_EQ(f.handles[2].status, HandlePose::kDisabled);
  EXPECT_EQ(f.handles[2].frame, 0u);
  EXPECT_TRUE(f.has_system_status);
  EXPECT_EQ(f.system_status, 0u);
}

TEST(AuroraTx, OutOfVolumeUnoccupiedAndDisabledWithStatus) {
  const std::string t =
      "03"
      "0A+10000+00000+00000+00000+000000+000000-010000+00100"
      "00000071"
      "00000002"
      "\n"
      "0BUNOCCUPIED\n"
      "0CDISABLED"
      "00000000"
      "00000000"
      "\n"
      "0102";
  BxFrame f;
  std::string err;
  ASSERT_TRUE(parse_tx_reply(t, kDefaultOutOfVolumeMask, &f, &err)) << err;
  ASSERT_EQ(f.handles.size(), 2u);                           // the unoccupied handle is skipped
  EXPECT_EQ(f.handles[0].status, HandlePose::kOutOfVolume);  // port status bit 0x40
  EXPECT_TRUE(f.handles[0].has_transform());
  EXPECT_EQ(f.handles[1].handle, 0x0C);
  EXPECT_EQ(f.handles[1].status, HandlePose::kDisabled);
  EXPECT_EQ(f.system_status, 0x0102);
  // The same port status is valid when the mask leaves bit 6 out.
  ASSERT_TRUE(parse_tx_reply(t, 0x80, &f, &err)) << err;
  EXPECT_EQ(f.handles[0].status, HandlePose::kValid);
}

TEST(AuroraTx, MalformedRepliesRejectedWithAReason) {
  const struct {
    std::string text;
    const char* reason;
  } cases[] = {
      {"", "handle count"},
      {"0G", "handle count"},
      {kTxNominal.substr(0, kTxNominal.size() - 4 - 11) + "0000", "handle entry 2"},  // 2 of 3 entries
      {"01"
       "0A+20000+00000+00000+00000+000000+000000+000000+00000"
       "00000031"
       "00000001"
       "\n"
       "0000",
       "quaternion norm"},
      {"01"
       "0A+10000+00000+00000+00000+000000+000000+000000-00001"
       "00000031"
       "00000001"
       "\n"
       "0000",
       "negative rms"},
      {"01"
       "0A 10000+00000+00000+00000+000000+000000+000000+00000"
       "00000031"
       "00000001"
       "\n"
       "0000",
       "field q0"},
      {"01"
       "0A+10000+00000+00000+00000+0000x0+000000+000000+00000"
       "00000031"
       "00000001"
       "\n"
       "0000",
       "field tx"},
      {"01"
       "0AMISSING"
       "0000003"
       "00000001"
       "\n"
       "0000",
       "8 hex digits"},
      {"01"
       "0AMISSING"
       "00000031"
       "00000001"
       "0000",
       "line feed"},
      {"01"
       "0AMISSING"
       "00000031"
       "00000001"
       "\n"
       "000",
       "system status"},
      {"01"
       "0AMISSING"
       "00000031"
       "00000001"
       "\n"
       "0000X",
       "system status"},
      {"01"
       "ZZMISSING"
       "00000031"
       "00000001"
       "\n"
       "0000",
       "port handle"},
      {"FF"
       "0AMISSING"
       "00000031"
       "00000001"
       "\n"
       "0000",
       "handle entry 1"},
  };
  for (const auto& c : cases) {
    BxFrame f;
    std::string err;
    EXPECT_FALSE(parse_tx_reply(c.text, kDefaultOutOfVolumeMask, &f, &err)) << c.text;
    EXPECT_NE(err.find(c.reason), std::string::npos) << "text: " << c.text << "\nerr: " << err;
  }
}

TEST(AuroraTx, EveryTruncationAndByteFlipIsRejectedNeverCrashes) {
  BxFrame f;
  for (size_t n = 0; n < kTxNominal.size(); ++n) {
    std::string err;
    EXPECT_FALSE(parse_tx_reply(kTxNominal.substr(0, n), kDefaultOutOfVolumeMask, &f, &err)) << n;
    EXPECT_FALSE(err.empty());
  }
  // Random byte values at every position: never a crash; a reply still accepted must decode to
  // finite, unit quaternions (the CRC, not this parser, is what catches a changed digit).
  std::mt19937 rng(5);
  for (size_t i = 0; i < kTxNominal.size(); ++i) {
    for (int k = 0; k < 8; ++k) {
      std::string t = kTxNominal;
      t[i] = static_cast<char>(rng() % 256);
      std::string err;
      if (parse_tx_reply(t, kDefaultOutOfVolumeMask, &f, &err)) {
        for (const HandlePose& h : f.handles)
          if (h.has_transform()) {
            EXPECT_NEAR(h.q[0] * h.q[0] + h.q[1] * h.q[1] + h.q[2] * h.q[2] + h.q[3] * h.q[3], 1.0, 1e-12);
          }
      }
    }
  }
}

TEST(AuroraPvwr, ChunksAddressesAndPadding) {
  std::vector<uint8_t> rom(65);
  for (size_t i = 0; i < rom.size(); ++i) rom[i] = static_cast<uint8_t>(0xA0 + i);
  const std::vector<std::string> p = pvwr_params(0x0A, rom);
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].size(), 2u + 4u + 128u);
  EXPECT_EQ(p[0].substr(0, 10), "0A0000A0A1");
  EXPECT_EQ(p[0].substr(132), "DF");         // byte 63 = 0xA0 + 63
  EXPECT_EQ(p[1].substr(0, 8), "0A0040E0");  // byte 64 = 0xE0, then 63 bytes of padding
  EXPECT_EQ(p[1].substr(8), std::string(126, '0'));
  EXPECT_EQ(pvwr_params(0x0B, std::vector<uint8_t>(1024, 0xFF)).back().substr(0, 6), "0B03C0");
  EXPECT_THROW(pvwr_params(0x0A, {}), std::invalid_argument);
  EXPECT_THROW(pvwr_params(0x0A, std::vector<uint8_t>(1025)), std::invalid_argument);
  // Each chunk goes out as a valid command.
  EXPECT_EQ(format_command("PVWR", p[1]).size(), 5u + 134u + 4u + 1u);
}

// ---------------------------------------------------------------------------------------------
// Flow-sensor lines
// ---------------------------------------------------------------------------------------------

TEST(FlowLine, FieldIndex) {
  FlowLineFormat fmt;
  fmt.field_index = 1;
  fmt.separator = ',';
  fmt.scale_to_m3_per_s = kMlPerMinToM3PerS;
  double q = -1.0;
  std::string err;
  ASSERT_TRUE(parse_flow_line("S1, 120.5 ,mL/min\r\n", fmt, &q, &err)) << err;
  EXPECT_DOUBLE_EQ(q, 120.5e-6 / 60.0);
  ASSERT_TRUE(parse_flow_line("S1,+1.2e2,x", fmt, &q, &err)) << err;
  EXPECT_DOUBLE_EQ(q, 120e-6 / 60.0);
  ASSERT_TRUE(parse_flow_line("S1,-0.0,x", fmt, &q, &err)) << err;
  EXPECT_EQ(q, 0.0);
  EXPECT_FALSE(std::signbit(q));

  fmt.separator = ' ';
  fmt.field_index = 2;
  fmt.scale_to_m3_per_s = kLPerMinToM3PerS;
  ASSERT_TRUE(parse_flow_line("  FLOW \t 0  0.75  L/min", fmt, &q, &err)) << err;
  EXPECT_DOUBLE_EQ(q, 0.75e-3 / 60.0);
}

TEST(FlowLine, Regex) {
  FlowLineFormat fmt;
  fmt.regex = R"(Q=\s*([-+0-9.eE]+|nan|inf)\s*mL/min)";
  fmt.scale_to_m3_per_s = kMlPerMinToM3PerS;
  double q = 0.0;
  std::string err;
  ASSERT_TRUE(parse_flow_line("t=12.1 Q= 33.25 mL/min ok", fmt, &q, &err)) << err;
  EXPECT_DOUBLE_EQ(q, 33.25e-6 / 60.0);
  // Same pattern again (cached) and a different one.
  ASSERT_TRUE(parse_flow_line("Q=1mL/min", fmt, &q, &err)) << err;
  FlowLineFormat other = fmt;
  other.regex = R"(^(\d+(?:\.\d+)?)$)";
  ASSERT_TRUE(parse_flow_line("42", other, &q, &err)) << err;
  EXPECT_DOUBLE_EQ(q, 42e-6 / 60.0);
  EXPECT_FALSE(parse_flow_line("Q=nan mL/min", fmt, &q, &err));
  EXPECT_NE(err.find("non-finite"), std::string::npos);
  EXPECT_FALSE(parse_flow_line("Q=inf mL/min", fmt, &q, &err));
  EXPECT_NE(err.find("non-finite"), std::string::npos);
  EXPECT_FALSE(parse_flow_line("Q=-3 mL/min", fmt, &q, &err));
  EXPECT_EQ(err, "negative flow -3");
  EXPECT_FALSE(parse_flow_line("no reading", fmt, &q, &err));
  EXPECT_FALSE(parse_flow_line("Q=1.2.3 mL/min", fmt, &q, &err));
  EXPECT_NE(err.find("not a number"), std::string::npos);
}

TEST(FlowLine, BadLinesAndFormatsRejected) {
  FlowLineFormat fmt;
  fmt.field_index = 0;
  fmt.scale_to_m3_per_s = kMlPerMinToM3PerS;
  double q = 123.0;
  std::string err;
  for (const char* bad : {"", "abc", "12abc", "1;2", " , 3", "0x10", "nan", "-inf", "--1", "+-1", "+"}) {
    fmt.field_index = 0;
    EXPECT_FALSE(parse_flow_line(bad, fmt, &q, &err)) << bad;
    EXPECT_FALSE(err.empty());
  }
  EXPECT_EQ(q, 123.0);  // untouched on failure
  EXPECT_FALSE(parse_flow_line("-1e-9", fmt, &q, &err));
  EXPECT_EQ(err.rfind("negative flow", 0), 0u);
  fmt.field_index = 3;
  EXPECT_FALSE(parse_flow_line("1,2", fmt, &q, &err));
  fmt.field_index = -1;
  EXPECT_FALSE(parse_flow_line("1,2", fmt, &q, &err));
  fmt.field_index = 0;
  fmt.scale_to_m3_per_s = 0.0;  // unit not stated
  EXPECT_FALSE(parse_flow_line("1", fmt, &q, &err));
  fmt.scale_to_m3_per_s = kNaN;
  EXPECT_FALSE(parse_flow_line("1", fmt, &q, &err));
  fmt.scale_to_m3_per_s = 1.0;
  fmt.regex = "(unclosed";
  EXPECT_FALSE(parse_flow_line("1", fmt, &q, &err));
  EXPECT_NE(err.find("invalid regex"), std::string::npos);
  fmt.regex = R"(\d+)";  // no capture group
  EXPECT_FALSE(parse_flow_line("1", fmt, &q, &err));
  EXPECT_NE(err.find("capture group"), std::string::npos);
  fmt.regex = R"((\d+)|(x))";  // group 1 does not participate in this match
  EXPECT_FALSE(parse_flow_line("x", fmt, &q, &err));
}

// ---------------------------------------------------------------------------------------------
// Valve board
// ---------------------------------------------------------------------------------------------

TEST(Valve, CommandFormat) {
  EXPECT_EQ(format_valve_command({0.25, 0.5, 1.0}), "V,0.2500,0.5000,1.0000*67\n");
  EXPECT_EQ(valve_checksum("V,0.2500,0.5000,1.0000"), 0x67);
  // Clamping and rounding to 4 decimals.
  EXPECT_EQ(format_valve_command({-0.2, 1.7, 0.123456}).substr(0, 23), "V,0.0000,1.0000,0.1235*");
  EXPECT_EQ(format_valve_command({-0.0, 0.0, 0.0}).substr(0, 23), "V,0.0000,0.0000,0.0000*");
  EXPECT_THROW(format_valve_command({kNaN, 0.0, 0.0}), std::invalid_argument);
  EXPECT_THROW(format_valve_command({0.0, std::numeric_limits<double>::infinity(), 0.0}), std::invalid_argument);
}

TEST(Valve, CommandAckRoundTrip) {
  const std::array<double, 3> sent = {0.1, 0.2345, 0.99999};
  const std::string cmd = format_valve_command(sent);
  std::array<double, 3> board{};
  std::string err;
  ASSERT_TRUE(parse_valve_command(cmd, &board, &err)) << err;
  for (size_t k = 0; k < 3; ++k) EXPECT_NEAR(board[k], std::min(sent[k], 1.0), 5e-5);
  const std::string ack = format_valve_ack(board);
  EXPECT_EQ(ack[0], 'A');
  std::array<double, 3> echoed{};
  ASSERT_TRUE(parse_valve_ack(ack, &echoed, &err)) << err;
  for (size_t k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(echoed[k], board[k]);
  EXPECT_TRUE(parse_valve_ack(ack, &err));
  EXPECT_TRUE(parse_valve_ack("A,0.2500,0.5000,1.0000*70\r\n", &err)) << err;
  EXPECT_TRUE(parse_valve_command("V,0.2500,0.5000,1.0000*67", &board, &err)) << err;  // no '\n'
  // Short numbers and a lower-case checksum are accepted on the board side.
  const uint8_t c = valve_checksum("V,0.25,0.5,1");
  const std::string lower = std::string("V,0.25,0.5,1*") + "0123456789abcdef"[c >> 4] + "0123456789abcdef"[c & 15];
  EXPECT_TRUE(parse_valve_command(lower, &board, &err)) << err;
  EXPECT_DOUBLE_EQ(board[2], 1.0);
}

TEST(Valve, ChecksumErrorsDetected) {
  std::string cmd = format_valve_command({0.25, 0.5, 1.0});
  std::array<double, 3> d{};
  std::string err;
  std::string bad = cmd;
  bad[3] = '3';  // 0.2500 -> 0.3500, checksum unchanged
  EXPECT_FALSE(parse_valve_command(bad, &d, &err));
  EXPECT_NE(err.find("checksum mismatch"), std::string::npos);
  bad = cmd;
  bad[bad.size() - 2] = (bad[bad.size() - 2] == '0') ? '1' : '0';
  EXPECT_FALSE(parse_valve_command(bad, &d, &err));
  std::string ack = format_valve_ack({0.25, 0.5, 1.0});
  ack[5] = '9';
  EXPECT_FALSE(parse_valve_ack(ack, &err));
  EXPECT_NE(err.find("checksum"), std::string::npos);
}

TEST(Valve, MalformedLinesRejected) {
  std::array<double, 3> d = {9, 9, 9};
  std::string err;
  auto framed = [](const std::string& payload) {
    static const char kHex[] = "0123456789ABCDEF";
    const uint8_t c = valve_checksum(payload);
    return payload + "*" + kHex[c >> 4] + kHex[c & 15] + "\n";
  };
  EXPECT_FALSE(parse_valve_command(framed("V,0.1,0.2"), &d, &err));          // 2 fields
  EXPECT_FALSE(parse_valve_command(framed("V,0.1,0.2,0.3,0.4"), &d, &err));  // 4 fields
  EXPECT_FALSE(parse_valve_command(framed("V,nan,0.2,0.3"), &d, &err));      // NaN
  EXPECT_NE(err.find("not finite"), std::string::npos);
  EXPECT_FALSE(parse_valve_command(framed("V,1.0001,0.2,0.3"), &d, &err));  // > 1
  EXPECT_FALSE(parse_valve_command(framed("V,-0.1,0.2,0.3"), &d, &err));    // < 0
  EXPECT_FALSE(parse_valve_command(framed("V,abc,0.2,0.3"), &d, &err));
  EXPECT_FALSE(parse_valve_command(framed("V,,0.2,0.3"), &d, &err));
  EXPECT_FALSE(parse_valve_command(framed("A,0.1,0.2,0.3"), &d, &err));  // wrong type
  EXPECT_FALSE(parse_valve_command(framed("V0.1,0.2,0.3"), &d, &err));
  EXPECT_FALSE(parse_valve_command("V,0.1,0.2,0.3\n", &d, &err));     // no checksum
  EXPECT_FALSE(parse_valve_command("V,0.1,0.2,0.3*G1\n", &d, &err));  // not hex
  EXPECT_FALSE(parse_valve_command("V,0.1,0.2,0.3*1\n", &d, &err));
  EXPECT_FALSE(parse_valve_command("", &d, &err));
  EXPECT_FALSE(parse_valve_command(framed("V,0.1,0.2,0.3" + std::string(80, '0')), &d, &err));
  EXPECT_EQ(d[0], 9.0);                                          // untouched on failure
  EXPECT_FALSE(parse_valve_ack(framed("V,0.1,0.2,0.3"), &err));  // not an ack
  EXPECT_FALSE(parse_valve_ack(framed("A,0.1,0.2"), &err));
}

TEST(Valve, NackReported) {
  const std::string nack = format_valve_nack("checksum*bad\n");
  EXPECT_EQ(nack.substr(0, 15), "N,checksum_bad_");
  std::string err;
  EXPECT_FALSE(parse_valve_ack(nack, &err));
  EXPECT_EQ(err, "valve board rejected command: checksum_bad_");
  EXPECT_FALSE(parse_valve_ack(format_valve_nack(""), &err));
  EXPECT_EQ(err, "valve board rejected command: unspecified");
  const std::string longn = format_valve_nack(std::string(200, 'x'));
  EXPECT_LE(longn.size(), kValveMaxLineLength + 1);
  EXPECT_FALSE(parse_valve_ack(longn, &err));
  EXPECT_NE(err.find("rejected"), std::string::npos);
}
