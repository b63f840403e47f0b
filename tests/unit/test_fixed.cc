// core/base/fixed.h's rounding and saturation primitives on exact cases:
// ties (which go toward +infinity, for negative values too), both ends of
// each range, and UScale's renormalisation and shifts of 64 and above. Each
// expected value is worked out from the header's rule in the comment beside
// it, not from the code.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

#include "core/base/fixed.h"

namespace camsim {
namespace {

constexpr uint64_t kU64Max = std::numeric_limits<uint64_t>::max();
constexpr int64_t kI64Min = std::numeric_limits<int64_t>::min();

TEST(FixedPoint, RoundShiftTiesGoUpForNegativesToo) {
  EXPECT_EQ(RoundShift(7, 0), 7);
  EXPECT_EQ(RoundShift(5, 1), 3);     // 2.5 -> 3
  EXPECT_EQ(RoundShift(1, 1), 1);     // 0.5 -> 1
  EXPECT_EQ(RoundShift(-1, 1), 0);    // -0.5 -> 0
  EXPECT_EQ(RoundShift(-5, 1), -2);   // -2.5 -> -2
  EXPECT_EQ(RoundShift(-6, 2), -1);   // -1.5 -> -1
  EXPECT_EQ(RoundShift(-7, 2), -2);   // -1.75 -> -2
  EXPECT_EQ(RoundShift(-5, 2), -1);   // -1.25 -> -1
  // -2^20 - 0.5 at 20 bits: the tie goes up, to -2^20.
  EXPECT_EQ(RoundShift(-(int64_t{1} << 40) - (int64_t{1} << 19), 20), -(int64_t{1} << 20));
  EXPECT_EQ(RoundShift(-(int64_t{1} << 40) - (int64_t{1} << 19) - 1, 20), -(int64_t{1} << 20) - 1);
}

TEST(FixedPoint, RoundShiftUDoesNotOverflowNearTwoToThe64) {
  EXPECT_EQ(RoundShiftU(0, 5), 0u);
  EXPECT_EQ(RoundShiftU(1, 1), 1u);                        // 0.5 -> 1
  EXPECT_EQ(RoundShiftU(3, 1), 2u);                        // 1.5 -> 2
  EXPECT_EQ(RoundShiftU(kU64Max, 1), uint64_t{1} << 63);   // 2^63 - 0.5 -> 2^63
  EXPECT_EQ(RoundShiftU(kU64Max, 63), 2u);                 // 1.99.. -> 2
  EXPECT_EQ(RoundShiftU((uint64_t{1} << 63) - 1, 63), 1u);  // 0.99.. -> 1
  EXPECT_EQ(RoundShiftU((uint64_t{1} << 62) - 1, 63), 0u);  // 0.49.. -> 0
  EXPECT_EQ(RoundShiftU(uint64_t{1} << 62, 63), 1u);        // 0.5 -> 1
}

TEST(FixedPoint, SatU32ClampsBothWays) {
  EXPECT_EQ(SatU32(int64_t{-1}), 0u);
  EXPECT_EQ(SatU32(kI64Min), 0u);
  EXPECT_EQ(SatU32(int64_t{0xFFFFFFFF}), 0xFFFFFFFFu);
  EXPECT_EQ(SatU32(int64_t{0x100000000}), 0xFFFFFFFFu);
  EXPECT_EQ(SatU32(uint64_t{0x100000000}), 0xFFFFFFFFu);
  EXPECT_EQ(SatU32(kU64Max), 0xFFFFFFFFu);
  EXPECT_EQ(SatU32(uint64_t{12345}), 12345u);
}

// The factor as mant * 2^-shift with mant in [2^31, 2^32), rounded once
// (ties up).
TEST(FixedPoint, UScaleFromDoubleNormalisesAndRoundsOnce) {
  const auto scale = [](double f) {
    const Result<UScale> s = UScale::FromDouble(f, "f");
    EXPECT_TRUE(s.ok()) << f << ": " << s.status().message();
    return s.ok() ? s.value() : UScale{};
  };
  EXPECT_EQ(scale(1.0).mant, 1u << 31);  // 2^31 * 2^-31
  EXPECT_EQ(scale(1.0).shift, 31);
  EXPECT_EQ(scale(0.75).mant, 3u << 30);  // 3 * 2^30 * 2^-32
  EXPECT_EQ(scale(0.75).shift, 32);
  EXPECT_EQ(scale(3.0).mant, 3u << 30);
  EXPECT_EQ(scale(3.0).shift, 30);
  EXPECT_EQ(scale(2147483648.0).shift, 0);
  EXPECT_EQ(scale(4294967295.0).mant, 0xFFFFFFFFu);
  EXPECT_EQ(scale(4294967295.25).mant, 0xFFFFFFFFu);  // .25 rounds down
  // 1 + 2^-33: 2^31 + 0.25 rounds down; 1 + 2^-32: 2^31 + 0.5 is a tie, up.
  EXPECT_EQ(scale(1.0 + std::ldexp(1.0, -33)).mant, 1u << 31);
  EXPECT_EQ(scale(1.0 + std::ldexp(1.0, -32)).mant, (1u << 31) + 1);
  // 1 - 2^-34: 2^32 - 0.25 rounds up to 2^32, renormalised to 2^31 * 2^-31.
  EXPECT_EQ(scale(1.0 - std::ldexp(1.0, -34)).mant, 1u << 31);
  EXPECT_EQ(scale(1.0 - std::ldexp(1.0, -34)).shift, 31);
  // The smallest: 2^-64 is 2^31 * 2^-95; below it, zero.
  EXPECT_EQ(scale(std::ldexp(1.0, -64)).mant, 1u << 31);
  EXPECT_EQ(scale(std::ldexp(1.0, -64)).shift, UScale::kMaxShift);
  EXPECT_EQ(scale(std::ldexp(1.0, -70)).mant, 0u);
  EXPECT_EQ(scale(0.0).mant, 0u);
  // A tie at the top rounds up to 2^32, which needs a negative shift.
  EXPECT_FALSE(UScale::FromDouble(4294967295.5, "f").ok());
  EXPECT_FALSE(UScale::FromDouble(4294967296.0, "f").ok());
  EXPECT_FALSE(UScale::FromDouble(-1.0, "f").ok());
  EXPECT_FALSE(UScale::FromDouble(std::nan(""), "f").ok());
}

// round(x * mant / 2^shift), ties up, saturated at 2^32 - 1.
TEST(FixedPoint, UScaleApplyRoundsAndSaturatesAtEveryShift) {
  const UScale half{1u << 31, 32};
  EXPECT_EQ(half.Apply(1), 1u);                    // 0.5 -> 1
  EXPECT_EQ(half.Apply(3), 2u);                    // 1.5 -> 2
  EXPECT_EQ(half.Apply(0xFFFFFFFFu), 1u << 31);    // 2^31 - 0.5 -> 2^31
  const UScale three{3u << 30, 30};
  EXPECT_EQ(three.Apply(0x55555555u), 0xFFFFFFFFu);  // exactly 2^32 - 1
  EXPECT_EQ(three.Apply(0x55555556u), 0xFFFFFFFFu);  // 2^32 + 2: saturated
  const UScale unit{1u << 31, 31};
  EXPECT_EQ(unit.Apply(0xFFFFFFFFu), 0xFFFFFFFFu);
  // Shift 64: p / 2^64 with p < 2^64 rounds to 1 exactly when p >= 2^63.
  EXPECT_EQ((UScale{1u << 31, 64}).Apply(0xFFFFFFFFu), 0u);         // p = 2^63 - 2^31
  EXPECT_EQ((UScale{(1u << 31) + 1, 64}).Apply(0xFFFFFFFFu), 1u);   // p > 2^63
  EXPECT_EQ((UScale{1u << 31, 64}).Apply(1u << 31), 0u);            // 2^-2 -> 0 (p = 2^62)
  EXPECT_EQ((UScale{0xFFFFFFFFu, 64}).Apply(0xFFFFFFFFu), 1u);      // 0.99.. -> 1
  // Above 64 every product is below half a unit.
  EXPECT_EQ((UScale{0xFFFFFFFFu, 65}).Apply(0xFFFFFFFFu), 0u);
  EXPECT_EQ((UScale{0xFFFFFFFFu, UScale::kMaxShift}).Apply(0xFFFFFFFFu), 0u);
}

// round(v * 2^F), ties up (toward +infinity), clamped to the format; NaN is 0.
TEST(FixedPoint, QFromDoubleTiesGoUpAndClamps) {
  using U = Q<8, 8>;
  using S = Q<8, 8, true>;
  EXPECT_EQ(U::FromDouble(std::ldexp(1.0, -9)).raw, 1u);           // 0.5 LSB -> 1
  EXPECT_EQ(U::FromDouble(std::ldexp(1.0, -10)).raw, 0u);          // 0.25 LSB -> 0
  EXPECT_EQ(S::FromDouble(-std::ldexp(1.0, -9)).raw, 0);           // -0.5 LSB -> 0
  EXPECT_EQ(S::FromDouble(-3 * std::ldexp(1.0, -9)).raw, -1);      // -1.5 LSB -> -1
  EXPECT_EQ(S::FromDouble(-5 * std::ldexp(1.0, -10)).raw, -1);     // -1.25 LSB -> -1
  EXPECT_EQ(U::FromDouble(1e9).raw, (1u << 16) - 1);
  EXPECT_EQ(U::FromDouble(-1.0).raw, 0u);
  EXPECT_EQ(S::FromDouble(-1e9).raw, -(1 << 16));
  EXPECT_EQ(S::FromDouble(1e9).raw, (1 << 16) - 1);
  EXPECT_EQ(U::FromDouble(std::nan("")).raw, 0u);
  EXPECT_EQ(S::FromDouble(255.99609375).raw, (1 << 16) - 1);  // the largest value, exactly
}

}  // namespace
}  // namespace camsim
