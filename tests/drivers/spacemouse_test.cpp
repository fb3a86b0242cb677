// SpaceMouse report decoding (the public hidraw report format) and identity table.
#include "drivers/spacemouse.hpp"
#include "drivers/usb_ids.hpp"

#include <CppUTest/TestHarness.h>

using namespace haptic::drivers;

TEST_GROUP(SpaceMouseReports) {};

TEST(SpaceMouseReports, TranslationRotationAndButtonReportsAreDecoded) {
  SpaceMouseState s{};
  const std::uint8_t t[7] = {1, 0x10, 0x00, 0xF0, 0xFF, 0x5E, 0x01};  // 16, -16, 350
  CHECK(decode_spacemouse_report(t, sizeof t, s));
  LONGS_EQUAL(16, s.translation[0]);
  LONGS_EQUAL(-16, s.translation[1]);
  LONGS_EQUAL(350, s.translation[2]);
  const std::uint8_t r[7] = {2, 0xA2, 0xFE, 0x00, 0x00, 0x01, 0x00};  // -350, 0, 1
  CHECK(decode_spacemouse_report(r, sizeof r, s));
  LONGS_EQUAL(-350, s.rotation[0]);
  LONGS_EQUAL(1, s.rotation[2]);
  const std::uint8_t b[3] = {3, 0x03, 0x00};
  CHECK(decode_spacemouse_report(b, sizeof b, s));
  LONGS_EQUAL(3, s.buttons);
  LONGS_EQUAL(3, s.reports);
}

TEST(SpaceMouseReports, CombinedTwelveByteReportCarriesRotationToo) {
  SpaceMouseState s{};
  const std::uint8_t t[13] = {1, 1, 0, 2, 0, 3, 0, 4, 0, 5, 0, 6, 0};
  CHECK(decode_spacemouse_report(t, sizeof t, s));
  LONGS_EQUAL(3, s.translation[2]);
  LONGS_EQUAL(6, s.rotation[2]);
}

TEST(SpaceMouseReports, ShortAndUnknownReportsAreIgnored) {
  SpaceMouseState s{};
  const std::uint8_t shortr[4] = {1, 1, 0, 2};
  const std::uint8_t unknown[7] = {0x17, 100, 0, 0, 0, 0, 0};  // battery report of wireless models
  CHECK_FALSE(decode_spacemouse_report(shortr, sizeof shortr, s));
  CHECK_FALSE(decode_spacemouse_report(unknown, sizeof unknown, s));
  LONGS_EQUAL(0, s.reports);
}

TEST(SpaceMouseReports, IdentityTableKnowsTheTouchAndTheSpaceMouseFamily) {
  CHECK(find_identity(0x2988, 0x0302)->kind == DeviceKind::kPhantomTouch);
  CHECK(find_identity(0x0301, 0x2988)->kind == DeviceKind::kPhantomTouch);
  CHECK(find_identity(0x256f, 0xc635)->kind == DeviceKind::kSpaceMouse);
  CHECK(find_identity(0x256f, 0x1234)->kind == DeviceKind::kSpaceMouse);
  CHECK(find_identity(0x046d, 0xc626)->kind == DeviceKind::kSpaceMouse);
  CHECK(find_identity(0x046d, 0xc52b) == nullptr);  // a Logitech receiver is not ours
}

TEST(SpaceMouseReports, SpaceMouseHasNoForceFeedbackAndSaysSo) {
  SpaceMouseConfig c;
  c.hidraw_path = "/nonexistent/hidraw9";
  SpaceMouseDevice d(c);
  DOUBLES_EQUAL(0.0, d.capabilities().max_force_N, 0.0);
  CHECK_FALSE(d.capabilities().actuated_axes[0]);
  CHECK(std::string(d.capabilities().name).find("NO force feedback") != std::string::npos);
  CHECK_THROWS(std::runtime_error, d.start());
}
