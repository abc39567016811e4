// NMEA parsing, WGS84->UTM, and the simulators' protocols (NMEA on a pty, CiA 402 on
// a CAN-frame socket) through the real device classes.
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>

#include "../unit/test_support.h"
#include "rack/devices/can_port.h"
#include "rack/devices/canopen.h"
#include "rack/devices/cola.h"
#include "rack/devices/nmea.h"
#include "rack/devices/scip.h"
#include "rack/devices/serial_port.h"
#include "rack/devices/utm.h"
#include "rack/sims/cia402_sim.h"
#include "rack/sims/nmea_gps_sim.h"

namespace rack::devices {
namespace {

using test::Watchdog;
namespace co = canopen;
constexpr int64_t kMs = rt::kNsPerMs;

std::size_t feed(NmeaParser& p, const std::string& s) {
  return p.feed(std::span(reinterpret_cast<const uint8_t*>(s.data()), s.size()));
}

// The textbook sentences (NMEA 0183 reference examples, as in gpsd's documentation).
const std::string kGga = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n";
const std::string kRmc = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n";
const std::string kGsa = "$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39\r\n";
const std::string kVtg = "$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\r\n";

TEST(NmeaTest, ParsesTheFourSentenceTypes) {
  NmeaParser p;
  EXPECT_EQ(feed(p, kGga + kRmc + kGsa), 3U);
  const NmeaFix& f = p.fix();
  EXPECT_NEAR(f.latitude_deg, 48.0 + 7.038 / 60.0, 1e-9);
  EXPECT_NEAR(f.longitude_deg, 11.0 + 31.0 / 60.0, 1e-9);
  EXPECT_DOUBLE_EQ(f.altitude_m, 545.4);
  EXPECT_EQ(f.quality, 1);
  EXPECT_EQ(f.satellites, 8);
  EXPECT_EQ(f.mode, 3);
  EXPECT_DOUBLE_EQ(f.pdop, 2.5);
  EXPECT_DOUBLE_EQ(f.hdop, 1.3);
  EXPECT_DOUBLE_EQ(f.vdop, 2.1);
  EXPECT_NEAR(f.speed_mps, 22.4 * 1852.0 / 3600.0, 1e-9);
  EXPECT_DOUBLE_EQ(f.course_deg, 84.4);
  EXPECT_TRUE(f.rmc_valid);
  // 23 March 1994 12:35:19 UTC = 764426119 s since the epoch.
  EXPECT_EQ(f.utc_ns, 764426119LL * 1'000'000'000LL);
  EXPECT_EQ(feed(p, kVtg), 1U);
  EXPECT_DOUBLE_EQ(p.fix().course_deg, 54.7);
  EXPECT_NEAR(p.fix().speed_mps, 10.2 / 3.6, 1e-12);
  EXPECT_EQ(p.counters().sentences, 4U);
}

TEST(NmeaTest, SentencesSplitAcrossReadsAndOtherTalkers) {
  NmeaParser p;
  std::string gn = kGga;
  gn[2] = 'N';  // $GNGGA: the checksum changes by 'P'^'N'
  const std::size_t star = gn.find('*');
  char cs[3];
  std::snprintf(cs, sizeof cs, "%02X", NmeaParser::checksum(gn.data() + 1, star - 1));
  gn[star + 1] = cs[0];
  gn[star + 2] = cs[1];
  EXPECT_EQ(feed(p, gn.substr(0, 20)), 0U);
  EXPECT_EQ(feed(p, gn.substr(20)), 1U);
  EXPECT_EQ(p.fix().satellites, 8);
}

TEST(NmeaTest, WrongChecksumsGarbageAndBrokenFieldsChangeNothingAndAreCounted) {
  NmeaParser p;
  ASSERT_EQ(feed(p, kGga), 1U);
  const NmeaFix before = p.fix();
  std::string bad = kGga;
  bad[bad.find('*') + 2] = '8';
  EXPECT_EQ(feed(p, bad), 0U);
  EXPECT_EQ(p.counters().checksum_errors, 1U);
  EXPECT_EQ(feed(p, std::string("\x01\x02junk\xff", 8)), 0U);
  EXPECT_GE(p.counters().garbage_bytes, 7U);
  // A field that is not a number, with a correct checksum.
  std::string body = "GPGGA,123519,48x7.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,";
  char tail[8];
  std::snprintf(tail, sizeof tail, "*%02X\r\n", NmeaParser::checksum(body.data(), body.size()));
  EXPECT_EQ(feed(p, "$" + body + tail), 0U);
  // Minutes of 60 or more.
  body = "GPGGA,123519,4867.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,";
  std::snprintf(tail, sizeof tail, "*%02X\r\n", NmeaParser::checksum(body.data(), body.size()));
  EXPECT_EQ(feed(p, "$" + body + tail), 0U);
  EXPECT_EQ(p.counters().malformed, 2U);
  // No checksum at all, a truncated sentence followed by a good one, an endless line.
  EXPECT_EQ(feed(p, "$GPGGA,123519,4807.038,N\r\n"), 0U);
  EXPECT_EQ(feed(p, "$GPGGA,1235" + kGga), 1U);
  EXPECT_EQ(feed(p, "$" + std::string(500, 'A') + "\r\n"), 0U);
  EXPECT_EQ(p.counters().overlong, 1U);
  // Unknown types are counted apart from errors.
  body = "GPZDA,201530.00,04,07,2002,00,00";
  std::snprintf(tail, sizeof tail, "*%02X\r\n", NmeaParser::checksum(body.data(), body.size()));
  EXPECT_EQ(feed(p, "$" + body + tail), 0U);
  EXPECT_EQ(p.counters().unknown, 1U);
  EXPECT_DOUBLE_EQ(p.fix().latitude_deg, before.latitude_deg);
}

TEST(NmeaTest, NoFixLeavesThePositionAlone) {
  NmeaParser p;
  ASSERT_EQ(feed(p, kGga), 1U);
  const std::string body = "GPGGA,123520,,,,,0,00,,,M,,M,,";
  char tail[8];
  std::snprintf(tail, sizeof tail, "*%02X\r\n", NmeaParser::checksum(body.data(), body.size()));
  EXPECT_EQ(feed(p, "$" + body + tail), 1U);
  EXPECT_EQ(p.fix().quality, 0);
  EXPECT_NEAR(p.fix().latitude_deg, 48.1173, 1e-4);
}

TEST(UtmTest, CentralMeridianAndEquator) {
  // On the equator at a central meridian: exactly the false origin.
  const UtmPoint p = wgs84_to_utm(0.0, 3.0);
  EXPECT_EQ(p.zone, 31);
  EXPECT_NEAR(p.easting, 500000.0, 1e-6);
  EXPECT_NEAR(p.northing, 0.0, 1e-6);
  // On a central meridian the northing is k0 times the meridian arc: 4 984 944.378 m
  // from the equator to 45 deg on WGS84.
  const UtmPoint q = wgs84_to_utm(45.0, 9.0);
  EXPECT_EQ(q.zone, 32);
  EXPECT_NEAR(q.easting, 500000.0, 1e-6);
  EXPECT_NEAR(q.northing, 0.9996 * 4984944.378, 0.01);
  // Southern hemisphere: 10 000 km false northing, mirror image of the north.
  const UtmPoint s = wgs84_to_utm(-45.0, 9.0);
  EXPECT_FALSE(s.north);
  EXPECT_NEAR(s.northing, 10000000.0 - q.northing, 1e-6);
}

TEST(UtmTest, EastingIsSymmetricAndScaleIsRight) {
  const UtmPoint e = wgs84_to_utm(52.0, 10.0);
  const UtmPoint w = wgs84_to_utm(52.0, 8.0);
  EXPECT_NEAR(e.easting - 500000.0, 500000.0 - w.easting, 1e-6);
  EXPECT_NEAR(e.northing, w.northing, 1e-6);
  // One degree of longitude at 52 N is about 68.7 km (N radius of curvature * cos).
  const double a = 6378137.0, e2 = 0.00669437999014;
  const double s = std::sin(52.0 * M_PI / 180.0);
  const double nu = a / std::sqrt(1 - e2 * s * s);
  const double deg = nu * std::cos(52.0 * M_PI / 180.0) * M_PI / 180.0;
  // Transverse Mercator bends the parallel: to third order in the longitude offset l
  // the easting is k0 * arc * (1 - l^2/6 + cos^2(phi) l^2/3) (spherical approximation).
  const double l = M_PI / 180.0, c2 = std::pow(std::cos(52.0 * M_PI / 180.0), 2);
  EXPECT_NEAR(e.easting - 500000.0, 0.9996 * deg * (1.0 - l * l / 6.0 + c2 * l * l / 3.0), 0.05);
}

TEST(UtmTest, ZoneExceptionsAndForcedZone) {
  EXPECT_EQ(utm_zone(60.0, 5.0), 32);  // Norway
  EXPECT_EQ(utm_zone(60.0, 2.0), 31);
  EXPECT_EQ(utm_zone(78.0, 15.0), 33);  // Svalbard
  EXPECT_EQ(utm_zone(78.0, 25.0), 35);
  EXPECT_EQ(utm_zone(0.0, -180.0), 1);
  EXPECT_EQ(utm_zone(0.0, 179.9), 60);
  // A point just east of the 32/33 border, projected into 32: continuous with 32.
  const UtmPoint in32 = wgs84_to_utm(52.0, 12.001, 32);
  const UtmPoint at = wgs84_to_utm(52.0, 11.999, 32);
  EXPECT_EQ(in32.zone, 32);
  EXPECT_NEAR(in32.easting - at.easting, 0.002 * 68700.0 * 1.0, 2.0);
}

TEST(NmeaGpsSimTest, TheDriverPathReadsTheSimulatorsSentences) {
  Watchdog w;
  sims::NmeaGpsSim::Config c;
  c.period_ns = 20 * kMs;
  sims::NmeaGpsSim sim(c);
  sim.start();
  SerialPort port;
  std::string error;
  ASSERT_TRUE(port.open(sim.device().c_str(), 115200, error)) << error;
  NmeaParser p;
  std::array<uint8_t, 512> buf{};
  const int64_t end = rt::monotonic_ns() + 5 * rt::kNsPerSec;
  while (p.counters().sentences < 8 && rt::monotonic_ns() < end) {
    const IoResult r = port.read(buf, 200 * kMs);
    if (r.status == IoStatus::kOk) p.feed(std::span(buf.data(), r.bytes));
  }
  EXPECT_GE(p.counters().sentences, 8U);
  EXPECT_EQ(p.counters().checksum_errors, 0U);
  EXPECT_NEAR(p.fix().latitude_deg, c.latitude_deg, 1e-4);
  EXPECT_NEAR(p.fix().longitude_deg, c.longitude_deg, 1e-3);
  EXPECT_EQ(p.fix().satellites, c.satellites);
  EXPECT_EQ(p.fix().mode, 3);
  EXPECT_NEAR(p.fix().speed_mps, c.speed_mps, 0.01);
  EXPECT_NEAR(static_cast<double>(p.fix().utc_ns), static_cast<double>(rt::host_time_ns()), 5e9);
  sim.set_fault(sims::NmeaGpsSim::Fault::kBadChecksum);
  const uint64_t good = p.counters().sentences;
  const int64_t end2 = rt::monotonic_ns() + 5 * rt::kNsPerSec;
  while (p.counters().checksum_errors < 8 && rt::monotonic_ns() < end2) {
    const IoResult r = port.read(buf, 200 * kMs);
    if (r.status == IoStatus::kOk) p.feed(std::span(buf.data(), r.bytes));
  }
  EXPECT_GE(p.counters().checksum_errors, 8U);
  EXPECT_LE(p.counters().sentences, good + 4) << "at most the epoch in flight when the fault began";
  sim.stop();
}

// ---------------------------------------------------------------------------

class Cia402SimTest : public ::testing::Test {
 protected:
  void SetUp() override {
    int sv[2];
    ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    port_.adopt(sv[0]);
    sim_.attach(sv[1]);
    sim_.start();
  }
  void TearDown() override { sim_.stop(); }

  // Waits for a frame with this id, skipping others.
  bool wait_for(canid_t id, can_frame& f, int64_t timeout_ns = 1000 * kMs) {
    const int64_t end = rt::monotonic_ns() + timeout_ns;
    while (rt::monotonic_ns() < end) {
      if (port_.receive(f, 10 * kMs).status == IoStatus::kOk && f.can_id == id) return true;
    }
    return false;
  }
  co::SdoResponse sdo(const can_frame& request, uint8_t node) {
    EXPECT_EQ(port_.send(request).status, IoStatus::kOk);
    can_frame f{};
    if (!wait_for(co::kSdoTx + node, f)) return {};
    return co::parse_sdo_response(f, node);
  }

  sims::Cia402DriveSim sim_{{}};
  CanPort port_;
};

TEST_F(Cia402SimTest, ProfileVelocityThroughNmtSdoRpdoSyncAndTpdo) {
  Watchdog w;
  EXPECT_EQ(sdo(co::sdo_write(1, co::kObjModesOfOperation, 0, 3, 1), 1).kind, co::SdoResponse::Kind::kWriteOk);
  EXPECT_EQ(sdo(co::sdo_write(1, co::kObjHeartbeatTime, 0, 20, 2), 1).kind, co::SdoResponse::Kind::kWriteOk);
  EXPECT_EQ(sdo(co::sdo_write(1, co::kObjProfileAcceleration, 0, 100000, 4), 1).kind, co::SdoResponse::Kind::kWriteOk);
  const co::SdoResponse abort = sdo(co::sdo_write(1, 0x2345, 0, 1, 4), 1);
  EXPECT_EQ(abort.kind, co::SdoResponse::Kind::kAbort);
  EXPECT_EQ(abort.value, co::kAbortNoObject);
  for (const uint16_t cw : {co::kCwShutdown, co::kCwSwitchOn, co::kCwEnableOperation}) {
    EXPECT_EQ(sdo(co::sdo_write(1, co::kObjControlword, 0, cw, 2), 1).kind, co::SdoResponse::Kind::kWriteOk);
  }
  const co::SdoResponse sw = sdo(co::sdo_read(1, co::kObjStatusword, 0), 1);
  ASSERT_EQ(sw.kind, co::SdoResponse::Kind::kReadOk);
  EXPECT_EQ(sw.value & co::kSwStateMask, co::kSwOperationEnabled);
  can_frame f{};
  ASSERT_TRUE(wait_for(co::kHeartbeat + 1, f));
  EXPECT_EQ(f.data[0], co::kStatePreOperational);
  ASSERT_EQ(port_.send(co::nmt(co::kNmtStart, 1)).status, IoStatus::kOk);
  ASSERT_EQ(port_.send(co::rpdo1(1, co::kCwEnableOperation, 2000)).status, IoStatus::kOk);
  // The drive ramps to 2000 counts/s within 20 ms at 100000 counts/s^2.
  int32_t velocity = 0;
  const int64_t end = rt::monotonic_ns() + 3 * rt::kNsPerSec;
  while (velocity != 2000 && rt::monotonic_ns() < end) {
    rt::sleep_for(5 * kMs);
    ASSERT_EQ(port_.send(co::sync()).status, IoStatus::kOk);
    if (wait_for(co::kTpdo1 + 1, f, 200 * kMs)) velocity = static_cast<int32_t>(co::get_u32(&f.data[0]));
  }
  EXPECT_EQ(velocity, 2000);
  EXPECT_GT(sim_.state(1).position, 0.0);
  EXPECT_EQ(sim_.state(2).rpdos, 0U) << "node 2 is not addressed";
}

TEST_F(Cia402SimTest, ASilentDriveSendsNoHeartbeatAndAnswersNothing) {
  Watchdog w;
  EXPECT_EQ(sdo(co::sdo_write(2, co::kObjHeartbeatTime, 0, 10, 2), 2).kind, co::SdoResponse::Kind::kWriteOk);
  can_frame f{};
  ASSERT_TRUE(wait_for(co::kHeartbeat + 2, f));
  sim_.set_silent(2, true);
  rt::sleep_for(30 * kMs);
  while (port_.receive(f, 0).status == IoStatus::kOk) {
  }
  EXPECT_FALSE(wait_for(co::kHeartbeat + 2, f, 100 * kMs));
  EXPECT_EQ(sdo(co::sdo_read(2, co::kObjStatusword, 0), 2).kind, co::SdoResponse::Kind::kNone);
  sim_.set_silent(2, false);
  EXPECT_TRUE(wait_for(co::kHeartbeat + 2, f));
}

TEST_F(Cia402SimTest, GarbageOnTheBusIsCountedByThePort) {
  Watchdog w;
  sim_.inject_garbage(3);
  ASSERT_TRUE(test::eventually([&] {
    can_frame f{};
    (void)port_.receive(f, 10 * kMs);
    return port_.counters().malformed >= 6;
  }));
}

}  // namespace
}  // namespace rack::devices

// ---------------------------------------------------------------------------
// SCIP 2.0

namespace rack::devices {
namespace {

std::size_t scip_feed(scip::Parser& p, const std::string& s, int* scans = nullptr) {
  return p.feed(
      std::span(reinterpret_cast<const uint8_t*>(s.data()), s.size()),
      [](void* user, scip::Parser::Event e, const char*, const char*) {
        if (user != nullptr && e == scip::Parser::Event::kScan) ++*static_cast<int*>(user);
      },
      scans);
}

std::string scip_line(const std::string& payload) {
  return payload + scip::checksum(payload.data(), payload.size()) + "\n";
}

TEST(ScipTest, ChecksumAndEncodingAsTheSpecificationShowsThem) {
  EXPECT_EQ(scip::checksum("00", 2), 'P');  // "00P": the status line of every OK answer
  EXPECT_EQ(scip::checksum("99", 2), 'b');  // "99b": MD data follows
  char e[3];
  scip::encode3(5432, e);  // SCIP's example: 5432 mm = "1Dh"
  EXPECT_EQ(std::string(e, 3), "1Dh");
  EXPECT_EQ(scip::decode("1Dh", 3), 5432U);
  EXPECT_EQ(scip::decode("CB", 2), 1234U);  // 2-character example: 1234 = "CB"
}

TEST(ScipTest, ParsesParametersAndAScanSplitAcrossLines) {
  scip::Parser p;
  const std::string pp = "PP\n" + scip_line("00") + "DMIN:20;" + scip::checksum("DMIN:20", 7) + "\nDMAX:5600;" +
                         scip::checksum("DMAX:5600", 9) + "\nARES:1024;" + scip::checksum("ARES:1024", 9) +
                         "\nAMIN:44;" + scip::checksum("AMIN:44", 7) + "\nAMAX:725;" + scip::checksum("AMAX:725", 8) +
                         "\nAFRT:384;" + scip::checksum("AFRT:384", 8) + "\nSCAN:600;" + scip::checksum("SCAN:600", 8) +
                         "\n\n";
  EXPECT_EQ(scip_feed(p, pp), 1U);
  EXPECT_TRUE(p.parameters().complete());
  EXPECT_EQ(p.parameters().afrt, 384U);
  // 30 steps (100..129), 90 characters: one full 64-character line and one of 26.
  std::string data;
  for (uint32_t i = 0; i < 30; ++i) {
    char e[3];
    scip::encode3(1000 + i, e);
    data.append(e, 3);
  }
  const std::string scan = "MD0100012901000\n" + scip_line("99") + scip_line("0000") + scip_line(data.substr(0, 64)) +
                           scip_line(data.substr(64)) + "\n";
  int scans = 0;
  EXPECT_EQ(scip_feed(p, scan.substr(0, 50), &scans) + scip_feed(p, scan.substr(50), &scans), 1U);
  EXPECT_EQ(scans, 1);
  EXPECT_EQ(p.scan().count, 30U);
  EXPECT_EQ(p.scan().range_mm[0], 1000U);
  EXPECT_EQ(p.scan().range_mm[29], 1029U);
  EXPECT_EQ(p.scan().first_step, 100U);
  // A corrupted data line: the whole scan is dropped and counted.
  std::string bad = scan;
  bad[bad.size() - 30] = bad[bad.size() - 30] == '0' ? '1' : '0';
  EXPECT_EQ(scip_feed(p, bad, &scans), 0U);
  EXPECT_EQ(p.counters().checksum_errors, 1U);
  // Fewer values than the echo announces: malformed.
  const std::string short_scan = "MD0100012901000\n" + scip_line("99") + scip_line("0000") +
                                 scip_line(data.substr(0, 63)) + "\n";
  EXPECT_EQ(scip_feed(p, short_scan, &scans), 0U);
  EXPECT_EQ(p.counters().malformed, 1U);
  // Garbage without empty lines overflows the block and is counted, then parsing resumes.
  EXPECT_EQ(scip_feed(p, std::string(scip::kMaxBlock + 10, 'x')), 0U);
  EXPECT_EQ(p.counters().overflows, 1U);
  EXPECT_EQ(scip_feed(p, "\n\n" + scan, &scans), 1U);
  EXPECT_EQ(scans, 2);
}

}  // namespace
}  // namespace rack::devices

// ---------------------------------------------------------------------------
// CoLa-A

namespace rack::devices {
namespace {

std::size_t cola_feed(cola::Parser& p, const std::string& s, int* scans = nullptr) {
  return p.feed(
      std::span(reinterpret_cast<const uint8_t*>(s.data()), s.size()),
      [](void* user, const char*, std::size_t, bool is_scan) {
        if (user != nullptr && is_scan) ++*static_cast<int*>(user);
      },
      scans);
}

// A telegram as an LMS111 sends it (fields per SICK's telegram listing), 5 points.
const std::string kScanBody =
    "sSN LMDscandata 1 1 89A27F 0 0 343 347 277B3F9 277F7EC 0 0 0 0 0 1388 168 0 1 DIST1 3F800000 00000000 "
    "FFF92230 1388 5 3E8 7D0 BB8 0 FA0 0 0 0 0 0 0";

TEST(ColaTest, ParsesAnLmdScanDataTelegram) {
  cola::Parser p;
  int scans = 0;
  EXPECT_EQ(cola_feed(p, "\x02" + kScanBody + "\x03", &scans), 1U);
  ASSERT_EQ(scans, 1);
  const cola::Scan& s = p.scan();
  EXPECT_EQ(s.count, 5U);
  EXPECT_DOUBLE_EQ(s.start_angle_deg, -45.0);  // FFF92230 = -450000
  EXPECT_DOUBLE_EQ(s.step_deg, 0.5);           // 1388 = 5000
  EXPECT_EQ(s.scan_frequency_centihz, 5000U);  // 50 Hz
  EXPECT_EQ(s.scan_counter, 0x347U);
  EXPECT_FLOAT_EQ(s.range_m[0], 1.0F);
  EXPECT_FLOAT_EQ(s.range_m[2], 3.0F);
  EXPECT_FLOAT_EQ(s.range_m[3], 0.0F);
  EXPECT_FALSE(s.has_rssi);
}

TEST(ColaTest, MalformedTelegramsAndGarbageAreCountedAndChangeNothing) {
  cola::Parser p;
  ASSERT_EQ(cola_feed(p, "\x02" + kScanBody + "\x03"), 1U);
  int scans = 0;
  // Fewer points than announced.
  std::string shorter = kScanBody;
  shorter.replace(shorter.find("5 3E8"), 5, "C 3E8");  // 12 announced; 5 and the trailer follow
  cola_feed(p, "\x02" + shorter + "\x03", &scans);
  // A field that is not a number.
  std::string bad = kScanBody;
  bad.replace(bad.find("BB8"), 3, "BXB");
  cola_feed(p, "\x02" + bad + "\x03", &scans);
  // A truncated telegram followed by a good one.
  cola_feed(p, "\x02" + kScanBody.substr(0, 60) + "\x02" + kScanBody + "\x03", &scans);
  EXPECT_EQ(scans, 1);
  EXPECT_EQ(p.counters().malformed, 3U);
  cola_feed(p, "noise\x03\xff");
  EXPECT_EQ(p.counters().garbage_bytes, 7U);
  cola_feed(p, "\x02" + std::string(cola::kMaxTelegram + 5, 'A'));
  EXPECT_EQ(p.counters().overflows, 1U);
  // Other telegrams are passed on, not scans.
  EXPECT_EQ(cola_feed(p, "\x02sEA LMDscandata 1\x03", &scans), 1U);
  EXPECT_EQ(scans, 1);
  EXPECT_FLOAT_EQ(p.scan().range_m[0], 1.0F);
}

}  // namespace
}  // namespace rack::devices
