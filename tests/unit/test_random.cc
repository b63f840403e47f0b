#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/base/detmath.h"
#include "core/base/random.h"
#include "core/base/simd.h"
#include "tests/support/test_support.h"

namespace camsim {
namespace {

// FNV-1a 64 over the little-endian bytes of 32-bit words (platform independent).
class Fnv1a {
 public:
  void Add(uint32_t w) {
    for (int i = 0; i < 4; ++i) {
      h_ ^= (w >> (8 * i)) & 0xFFu;
      h_ *= 0x100000001B3ull;
    }
  }
  uint64_t value() const { return h_; }

 private:
  uint64_t h_ = 0xCBF29CE484222325ull;
};

// Known-answer vectors from Random123's kat_vectors (philox4x32 10):
// counter (4 words), key (2 words) -> output (4 words).
TEST(PhiloxTest, Random123KnownAnswers) {
  struct Kat {
    uint32_t ctr[4], key[2], out[4];
  };
  const Kat kats[] = {
      {{0x00000000, 0x00000000, 0x00000000, 0x00000000},
       {0x00000000, 0x00000000},
       {0x6627e8d5, 0xe169c58d, 0xbc57ac4c, 0x9b00dbd8}},
      {{0xffffffff, 0xffffffff, 0xffffffff, 0xffffffff},
       {0xffffffff, 0xffffffff},
       {0x408f276d, 0x41c83b0e, 0xa20bc7c6, 0x6d5451fd}},
      {{0x243f6a88, 0x85a308d3, 0x13198a2e, 0x03707344},
       {0xa4093822, 0x299f31d0},
       {0xd16cfe09, 0x94fdcceb, 0x5001e420, 0x24126ea1}},
  };
  for (const Kat& k : kats) {
    uint32_t out[4];
    Philox4x32::Generate(k.ctr, k.key, out);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(out[i], k.out[i]) << "word " << i;
  }
}

TEST(DrawBitsTest, KeyingIsAsDocumented) {
  const uint64_t seed = 0x0123456789ABCDEFull;
  const uint32_t stream = 7;
  const uint32_t ctr[4] = {100, 200, 3, 1};  // x, y, frame, draw
  const uint32_t key[2] = {0x89ABCDEFu, 0x01234567u ^ (7u * 0x9E3779B9u)};
  uint32_t expect[4];
  Philox4x32::Generate(ctr, key, expect);
  const RandomBits b = DrawBits(seed, stream, /*frame=*/3, /*x=*/100, /*y=*/200, /*draw=*/1);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(b.v[i], expect[i]);
  // Literal guard: any change to the keying or the counter layout shows here.
  EXPECT_EQ(b.v[0], 707350108u);
  EXPECT_EQ(b.v[1], 3181712583u);
  EXPECT_EQ(b.v[2], 3935705891u);
  EXPECT_EQ(b.v[3], 1874650373u);
}

TEST(DrawBitsTest, DeterministicAndSensitiveToEveryInput) {
  auto same = [](RandomBits a, RandomBits b) {
    return a.v[0] == b.v[0] && a.v[1] == b.v[1] && a.v[2] == b.v[2] && a.v[3] == b.v[3];
  };
  const RandomBits base = DrawBits(42, 1, 2, 3, 4, 5);
  EXPECT_TRUE(same(base, DrawBits(42, 1, 2, 3, 4, 5)));
  EXPECT_FALSE(same(base, DrawBits(43, 1, 2, 3, 4, 5)));
  EXPECT_FALSE(same(base, DrawBits(42 | (1ull << 40), 1, 2, 3, 4, 5)));  // high seed word
  EXPECT_FALSE(same(base, DrawBits(42, 2, 2, 3, 4, 5)));
  EXPECT_FALSE(same(base, DrawBits(42, 1, 3, 3, 4, 5)));
  EXPECT_FALSE(same(base, DrawBits(42, 1, 2, 4, 4, 5)));
  EXPECT_FALSE(same(base, DrawBits(42, 1, 2, 3, 5, 5)));
  EXPECT_FALSE(same(base, DrawBits(42, 1, 2, 3, 4, 6)));
  EXPECT_FALSE(
      same(DrawBits(42, 1, 0, 3, 4), DrawBits(42, 1, 0, 4, 3)));  // x and y not interchangeable
}

// DrawBitsLanes is DrawBits for 16 consecutive x, word for word, including
// an x0 where x0 + i wraps around 2^32.
TEST(DrawBitsTest, LanesMatchDrawBits) {
  struct Key {
    uint64_t seed;
    uint32_t stream, frame, x0, y, draw;
  };
  const Key keys[] = {{0, 0, 0, 0, 0, 0},
                      {1, 1, 3, 640, 479, 0},
                      {0x0123456789ABCDEFull, 2, 0, 1904, 1079, 2},
                      {~0ull, 0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFF8u, 0xFFFFFFFFu, 0xFFFFFFFFu}};
  std::vector<Key> all(std::begin(keys), std::end(keys));
  for (uint32_t i = 0; i < 64; ++i) {  // keys with every bit pattern in play
    const RandomBits r = DrawBits(i, 9, 0, i, 0);
    all.push_back({(uint64_t{r.v[0]} << 32) | r.v[1], r.v[2], r.v[3], r.v[1] ^ r.v[3], r.v[0] ^ r.v[2], i});
  }
  for (const Key& k : all) {
    RandomLanes lanes;
    DrawBitsLanes(k.seed, k.stream, k.frame, k.x0, k.y, k.draw, &lanes);
    for (int i = 0; i < RandomLanes::kLanes; ++i) {
      const RandomBits b = DrawBits(k.seed, k.stream, k.frame, k.x0 + static_cast<uint32_t>(i), k.y, k.draw);
      for (int w = 0; w < 4; ++w) EXPECT_EQ(lanes.v[w][i], b.v[w]) << "x0 " << k.x0 << " lane " << i << " word " << w;
    }
  }
}

// ISqrt64 (table + Newton + exact correction) against the definition,
// floor(sqrt(x)): r^2 <= x < (r + 1)^2, and against the bit-by-bit reference.
bool IsFloorSqrt(uint64_t x, uint64_t r) {
  return r <= 0xFFFFFFFFu && r * r <= x && x - r * r <= 2 * r;  // (r + 1)^2 > x without overflow
}

static_assert(ISqrt64(0) == 0 && ISqrt64(1) == 1 && ISqrt64(3) == 1 && ISqrt64(4) == 2);
static_assert(ISqrt64(~uint64_t{0}) == 0xFFFFFFFFu && ISqrt64(0xFFFFFFFE00000001ull) == 0xFFFFFFFFu &&
              ISqrt64(0xFFFFFFFE00000000ull) == 0xFFFFFFFEu);

TEST(ISqrt64Test, ExhaustiveBelow2To22) {
  for (uint64_t x = 0; x < (uint64_t{1} << 16); ++x) ASSERT_EQ(ISqrt64(x), ISqrt64BitByBit(x)) << x;
  // Every x in [r^2, (r + 1)^2) gives r.
  for (uint64_t r = 0; r < (uint64_t{1} << 11); ++r)
    for (uint64_t x = r * r; x < (r + 1) * (r + 1); ++x) ASSERT_EQ(ISqrt64(x), r) << x;
}

TEST(ISqrt64Test, PerfectSquaresAndNeighboursOverTheWholeRange) {
  auto check = [](uint64_t r) {
    ASSERT_EQ(ISqrt64(r * r), r) << r;
    if (r > 0) {
      ASSERT_EQ(ISqrt64(r * r - 1), r - 1) << r;
    }
    ASSERT_EQ(ISqrt64(r * r + 1), r + (r == 0 ? 1 : 0)) << r;
    ASSERT_EQ(ISqrt64(r * r + 2 * r), r) << r;  // (r + 1)^2 - 1
  };
  for (uint64_t r = 0; r <= 0xFFFFFFFFu; r += (r >> 13) + 1) check(r);   // ~2^18 r, every scale
  for (uint64_t r = 0xFFFFFFFFu - 65535; r <= 0xFFFFFFFFu; ++r) check(r);  // the top, up to 2^64 - 1
}

TEST(ISqrt64Test, PowersOfTwoTableCellEdgesAndExtremes) {
  for (int b = 0; b < 64; ++b) {
    const uint64_t p = uint64_t{1} << b;
    for (uint64_t x : {p - 1, p, p + 1}) EXPECT_EQ(ISqrt64(x), ISqrt64BitByBit(x)) << x;
  }
  // Both ends of every table cell (top 10 bits of the normalised x), at every scale.
  for (uint64_t i = 256; i <= 1024; ++i) {
    for (int shift = 0; shift < 64; shift += 2) {
      for (int d = -2; d <= 2; ++d) {
        const uint64_t x = ((i << 54) + static_cast<uint64_t>(d)) >> shift;  // i = 1024: 2^64 + d wraps
        ASSERT_EQ(ISqrt64(x), ISqrt64BitByBit(x)) << x;
      }
    }
  }
  EXPECT_EQ(ISqrt64(~uint64_t{0}), 0xFFFFFFFFu);
  EXPECT_EQ(ISqrt64(~uint64_t{0} - 1), 0xFFFFFFFFu);
}

TEST(ISqrt64Test, RandomValuesOfEveryMagnitude) {
  uint64_t s = 0x9E3779B97F4A7C15ull;  // splitmix64
  auto next = [&s] {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  };
  for (int i = 0; i < 2000000; ++i) {
    const uint64_t x = next() >> (i & 63);
    ASSERT_TRUE(IsFloorSqrt(x, ISqrt64(x))) << x;
  }
  for (int i = 0; i < 20000; ++i) {
    const uint64_t x = next() >> (i & 63);
    ASSERT_EQ(ISqrt64(x), ISqrt64BitByBit(x)) << x;
  }
}

// ISqrt64Lanes (AVX-512 or AVX2 lanes where the CPU has them) against
// ISqrt64 on the inputs of the tests above: small x, perfect squares and
// their neighbours, powers of two, both ends of every table cell at every
// scale, random values, and 0 and 2^64 - 1 between them in the same vector.
TEST(ISqrt64Test, LanesMatchScalar) {
  CAMSIM_SKIP_WITHOUT_LANE_KERNELS();
  std::vector<uint64_t> x;
  for (uint64_t v = 0; v < 4096; ++v) x.push_back(v);
  for (uint64_t r = 1; r <= 0xFFFFFFFFu; r += (r >> 11) + 1)
    for (uint64_t v : {r * r - 1, r * r, r * r + 1, r * r + 2 * r}) x.push_back(v);
  for (int b = 0; b < 64; ++b)
    for (uint64_t v : {(uint64_t{1} << b) - 1, uint64_t{1} << b, (uint64_t{1} << b) + 1}) x.push_back(v);
  // Halves with bit 31 set (negative as int32 in the lanes' exponent trick).
  for (uint64_t h : {0x80000000ull, 0xA0000000ull, 0xBFFFFFFFull, 0xC0000001ull, 0xFFFFFFFFull})
    for (uint64_t v : {h, h << 32, (h << 32) | h, (h << 32) | 1}) x.push_back(v);
  for (uint64_t i = 256; i <= 1024; ++i)
    for (int shift = 0; shift < 64; shift += 2)
      for (int d = -2; d <= 2; ++d) x.push_back(((i << 54) + static_cast<uint64_t>(d)) >> shift);
  uint64_t s = 0x0123456789ABCDEFull;
  for (int i = 0; i < 400000; ++i) {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    x.push_back((s ^ (s >> 29)) >> (i & 63));
    if (i % 97 == 0) x.push_back(i % 2 == 0 ? 0 : ~uint64_t{0});
  }
  std::vector<uint32_t> r(x.size());
  ISqrt64Lanes(x.data(), r.data(), static_cast<int>(x.size()));
  for (size_t i = 0; i < x.size(); ++i) ASSERT_EQ(r[i], ISqrt64(x[i])) << "x " << x[i] << " at " << i;
  // Every count, so that each length of the scalar tail runs.
  for (int n = 0; n <= 9; ++n) {
    std::vector<uint32_t> part(10, 0xDEADBEEFu);
    ISqrt64Lanes(x.data() + 4000, part.data(), n);
    for (int i = 0; i < 10; ++i) EXPECT_EQ(part[i], i < n ? ISqrt64(x[4000 + i]) : 0xDEADBEEFu) << n << " " << i;
  }
}

#ifdef CAMSIM_X86_AVX2
// avx2::FloorDiv6 and avx512::FloorDiv6 (the sensor's Poisson skew term in
// lanes) are floor(n / 6) for every n below 2^38: exhaustively below 2^24, on
// both sides of every multiple of 2^33 (where n / 2's high word steps), at
// the top of the range and at random.
std::vector<uint64_t> FloorDiv6Inputs() {
  constexpr uint64_t kLimit = uint64_t{1} << 38;
  std::vector<uint64_t> n;
  for (uint64_t v = 0; v < (1u << 24); ++v) n.push_back(v);
  for (uint64_t edge = 0; edge <= kLimit; edge += uint64_t{1} << 33)
    for (uint64_t d = 0; d < 4096; ++d) {
      if (edge + d < kLimit) n.push_back(edge + d);
      if (edge >= d + 1) n.push_back(edge - d - 1);
    }
  uint64_t s = 0x9E3779B97F4A7C15ull;
  for (int i = 0; i < 1 << 20; ++i) {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    n.push_back((s >> 26) >> (i % 38));
  }
  while (n.size() % 8 != 0) n.push_back(kLimit - 1);
  return n;
}

// kernel(n, q): q[j] = floor(n[j] / 6) for j < lanes.
void CheckFloorDiv6(int lanes, void (*kernel)(const uint64_t*, uint64_t*)) {
  const std::vector<uint64_t> n = FloorDiv6Inputs();
  uint64_t q[8];
  for (size_t i = 0; i < n.size(); i += static_cast<size_t>(lanes)) {
    kernel(&n[i], q);
    for (int j = 0; j < lanes; ++j) ASSERT_EQ(q[j], n[i + j] / 6) << "n " << n[i + j];
  }
}

CAMSIM_AVX2_TARGET void FloorDiv6x4(const uint64_t* n, uint64_t* q) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(q),
                      avx2::FloorDiv6(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(n))));
}

TEST(Avx2FloorDiv6, IsExactBelow2To38) {
  if (!CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  CheckFloorDiv6(4, FloorDiv6x4);
}
#endif

#ifdef CAMSIM_X86_AVX512
CAMSIM_AVX512_TARGET void FloorDiv6x8(const uint64_t* n, uint64_t* q) {
  _mm512_storeu_si512(q, avx512::FloorDiv6(_mm512_loadu_si512(n)));
}

TEST(Avx512FloorDiv6, IsExactBelow2To38) {
  if (!CpuHasAvx512()) GTEST_SKIP() << "no AVX-512 on this CPU";
  CheckFloorDiv6(8, FloorDiv6x8);
}
#endif

// DivideSmall (multiply by a reciprocal where there is a 128-bit product) is
// floor(n / d) for n < 2^57, 1 <= d <= 64: checked at the top of the range,
// where the proof's margin is smallest, at every remainder, and at random.
TEST(DivideSmallTest, IsExactDivision) {
  constexpr uint64_t kLimit = uint64_t{1} << 57;
  uint64_t s = 12345;
  for (uint32_t d = 1; d <= 64; ++d) {
    const uint64_t top = (kLimit - 1) / d;  // largest quotient
    for (uint64_t q : {uint64_t{0}, uint64_t{1}, top / 2, top - 1, top}) {
      for (uint64_t r = 0; r < d; ++r) {
        const uint64_t n = q * d + r;
        if (n >= kLimit) continue;
        ASSERT_EQ(DivideSmall(n, d), n / d) << n << " / " << d;
      }
    }
    for (int i = 0; i < 20000; ++i) {
      s = s * 6364136223846793005ull + 1442695040888963407ull;
      const uint64_t n = (s >> 7) >> (i & 31);
      ASSERT_EQ(DivideSmall(n, d), n / d) << n << " / " << d;
    }
  }
}

class GaussianTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(table_.Build({storage_.data(), storage_.size()}).ok()); }
  std::vector<int32_t> storage_ = std::vector<int32_t>(GaussianTable::kEntries);
  GaussianTable table_;
};

TEST(GaussianTableTest, BuildNeedsStorage) {
  std::vector<int32_t> small(GaussianTable::kEntries - 1);
  GaussianTable t;
  EXPECT_EQ(t.Build({small.data(), small.size()}).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(t.Build({nullptr, GaussianTable::kEntries}).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(GaussianTable::kEntries * sizeof(int32_t), 16384u);
}

// The documented bound: |Sample(u) - InvNormalCdf((u + 0.5) / 2^32)| <= 2.5e-5
// (measured 2.03e-5), checked on a stride through all u plus every segment's
// ends and the extreme tails.
TEST_F(GaussianTest, MatchesExactQuantileOfBucketMidpoint) {
  double worst = 0.0;
  auto check = [&](uint32_t u) {
    const double exact = detmath::InvNormalCdf((static_cast<double>(u) + 0.5) * 0x1p-32);
    worst = std::max(worst, std::fabs(table_.Sample(u) / 65536.0 - exact));
  };
  for (uint64_t u = 0; u < (uint64_t{1} << 32); u += 65521) check(static_cast<uint32_t>(u));
  for (int s = 0; s < 31; ++s) {
    for (int d = -2; d <= 2; ++d) {
      const uint32_t v = (1u << (30 - s)) + static_cast<uint32_t>(d);
      check(v);
      check(~v);
    }
  }
  for (uint32_t u = 0; u < 512; ++u) {
    check(u);
    check(~u);
  }
  EXPECT_LE(worst, 2.5e-5);
}

// SampleLanes (AVX-512 or AVX2 on this CPU when it has them) gives Sample's
// bits: a stride through all words, every segment's ends, both tails, and
// lengths that are not a multiple of the sixteen or eight lanes.
TEST_F(GaussianTest, LanesMatchSample) {
  CAMSIM_SKIP_WITHOUT_LANE_KERNELS();
  std::vector<uint32_t> u;
  for (uint64_t w = 0; w < (uint64_t{1} << 32); w += 4099) u.push_back(static_cast<uint32_t>(w));
  for (int s = 0; s < 31; ++s)
    for (int d = -2; d <= 2; ++d) {
      const uint32_t v = (1u << (30 - s)) + static_cast<uint32_t>(d);
      u.push_back(v);
      u.push_back(~v);
      u.push_back(v | 0x80000000u);
      u.push_back(v & 0x7FFFFFFFu);
    }
  for (uint32_t w = 0; w < 64; ++w) {
    u.push_back(w);
    u.push_back(~w);
    u.push_back(0x7FFFFFFFu - w);
    u.push_back(0x80000000u + w);
  }
  for (int n : {static_cast<int>(u.size()), 7, 9, 1, 17, 31, 33}) {
    std::vector<int32_t> z(static_cast<size_t>(n));
    table_.SampleLanes(u.data(), z.data(), n);
    for (size_t i = 0; i < z.size(); ++i) ASSERT_EQ(z[i], table_.Sample(u[i])) << u[i];
  }
}

TEST_F(GaussianTest, ExactProperties) {
  EXPECT_EQ(table_.Sample(0), -415364);  // quantile of 2^-33: -6.33795
  EXPECT_EQ(table_.Sample(0xFFFFFFFFu), 415364);
  EXPECT_EQ(table_.Sample(0x7FFFFFFFu), 0);
  EXPECT_EQ(table_.Sample(0x80000000u), 0);
  // Antisymmetric and non-decreasing (sampled, plus across every segment boundary).
  for (uint64_t u = 0; u + 1 < (uint64_t{1} << 32); u += 9973) {
    const uint32_t a = static_cast<uint32_t>(u);
    ASSERT_EQ(table_.Sample(~a), -table_.Sample(a)) << a;
    ASSERT_LE(table_.Sample(a), table_.Sample(a + 1)) << a;
  }
  for (int s = 0; s < 31; ++s) {
    const uint32_t b = 1u << (30 - s);
    ASSERT_LE(table_.Sample(b - 1), table_.Sample(b)) << s;
    ASSERT_LE(table_.Sample(~b), table_.Sample(~b + 1)) << s;
  }
}

TEST_F(GaussianTest, MomentsOverConsecutiveCounters) {
  constexpr int kN = 1 << 20;
  double sum = 0, sum2 = 0, sum3 = 0, sum4 = 0;
  int negative = 0;
  for (uint32_t x = 0; x < kN; ++x) {
    const double z = table_.Sample(DrawBits(2024, 1, 0, x, 0).v[0]) / 65536.0;
    sum += z;
    sum2 += z * z;
    sum3 += z * z * z;
    sum4 += z * z * z * z;
    negative += z < 0;
  }
  const double n = kN;
  // Standard errors for N(0,1): mean 1/sqrt(n), variance sqrt(2/n), third
  // moment sqrt(15/n), fourth moment sqrt(96/n), sign fraction 0.5/sqrt(n).
  EXPECT_LE(std::fabs(sum / n), 4.0 / std::sqrt(n));
  EXPECT_LE(std::fabs(sum2 / n - 1.0), 4.0 * std::sqrt(2.0 / n));
  EXPECT_LE(std::fabs(sum3 / n), 4.0 * std::sqrt(15.0 / n));
  EXPECT_LE(std::fabs(sum4 / n - 3.0), 4.0 * std::sqrt(96.0 / n));
  EXPECT_LE(std::fabs(negative / n - 0.5), 4.0 * 0.5 / std::sqrt(n));
}

// Bit-exactness guard. To regenerate after an intended change, run the test
// and copy the "Which is" value from the failure message.
TEST_F(GaussianTest, GoldenHash) {
  Fnv1a h;
  for (uint32_t x = 0; x < 4096; ++x) {
    const RandomBits b = DrawBits(0xC0FFEEull, 3, 0, x, 0);
    for (uint32_t w : b.v) h.Add(static_cast<uint32_t>(table_.Sample(w)));
  }
  EXPECT_EQ(h.value(), 4271767086218680712ull);
}

class PoissonTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(gauss_.Build({gstorage_.data(), gstorage_.size()}).ok());
    ASSERT_TRUE(table_.Build({storage_.data(), storage_.size()}).ok());
  }
  uint32_t Draw(uint32_t lambda_q8, uint32_t x, uint32_t y) const {
    const RandomBits b = DrawBits(77, 2, 0, x, y);
    return table_.Sample(lambda_q8, b.v[0], gauss_.Sample(b.v[1]));
  }
  std::vector<int32_t> gstorage_ = std::vector<int32_t>(GaussianTable::kEntries);
  std::vector<uint32_t> storage_ = std::vector<uint32_t>(PoissonTable::kEntries);
  GaussianTable gauss_;
  PoissonTable table_;
};

TEST(PoissonTableTest, BuildNeedsStorage) {
  std::vector<uint32_t> small(PoissonTable::kEntries - 1);
  PoissonTable t;
  EXPECT_EQ(t.Build({small.data(), small.size()}).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(PoissonTable::kEntries * sizeof(uint32_t), 12288u);
}

TEST_F(PoissonTest, ZeroMeanIsAlwaysZero) {
  for (uint64_t u = 0; u < (uint64_t{1} << 32); u += 12345677) {
    EXPECT_EQ(table_.Sample(0, static_cast<uint32_t>(u), 0), 0u);
  }
  EXPECT_EQ(table_.Sample(0, 0xFFFFFFFFu, 0), 0u);
  EXPECT_EQ(table_.Sample(0, 0xFFFFFFFFu, INT32_MAX), 0u);
}

// P(0) is exact up to table rounding: Sample(q, u) == 0 exactly for
// u < ceil(table[q] / 2^n), and that threshold is exp(-lambda) * 2^32 +- 1.
TEST_F(PoissonTest, ProbabilityOfZeroIsExact) {
  for (uint32_t q : {1u, 3u, 128u, 256u, 768u, 2000u, 3069u, 3071u}) {
    const uint32_t n = (q * 369u) >> 16;
    const uint64_t threshold = (uint64_t{storage_[q]} + (uint64_t{1} << n) - 1) >> n;
    ASSERT_GT(threshold, 0u);
    EXPECT_EQ(table_.Sample(q, static_cast<uint32_t>(threshold - 1), 0), 0u) << q;
    EXPECT_EQ(table_.Sample(q, static_cast<uint32_t>(threshold), 0), 1u) << q;
    EXPECT_NEAR(static_cast<double>(threshold), std::exp(-static_cast<double>(q) / 256.0) * 0x1p32,
                1.0)
        << q;
  }
}

// SampleSmallLanes against Sample for every small mean: u at both ends, on
// both sides of every step of the inverse transform (found by bisection on
// the scalar Sample), and random. Lanes that stop early sit next to lanes
// that search on, and the count is odd so that the scalar tail runs too.
TEST_F(PoissonTest, SmallLanesMatchSample) {
  CAMSIM_SKIP_WITHOUT_LANE_KERNELS();
  std::vector<uint32_t> lambda, u;
  std::mt19937 rng(11);
  for (uint32_t q = 0; q < PoissonTable::kSmallQ8; ++q) {
    const auto add = [&](uint64_t v) {
      lambda.push_back(q);
      u.push_back(static_cast<uint32_t>(v));
    };
    for (uint64_t v : {uint64_t{0}, uint64_t{1}, uint64_t{0xFFFFFFFE}, uint64_t{0xFFFFFFFF}}) add(v);
    for (int i = 0; i < 8; ++i) add(rng());
    for (uint32_t k = 0;; ++k) {  // the smallest u whose count exceeds k
      if (table_.Sample(q, 0xFFFFFFFFu, 0) <= k) break;
      uint64_t lo = 0, hi = 0xFFFFFFFFu;
      while (lo < hi) {
        const uint64_t mid = (lo + hi) / 2;
        if (table_.Sample(q, static_cast<uint32_t>(mid), 0) > k) hi = mid; else lo = mid + 1;
      }
      add(lo);
      if (lo > 0) add(lo - 1);
    }
  }
  lambda.push_back(5);  // an odd count
  u.push_back(12345);
  std::vector<uint32_t> count(lambda.size(), 0xDEADBEEFu);
  table_.SampleSmallLanes(lambda.data(), u.data(), count.data(), static_cast<int>(lambda.size()));
  for (size_t i = 0; i < lambda.size(); ++i)
    ASSERT_EQ(count[i], table_.Sample(lambda[i], u[i], 0)) << "lambda_q8 " << lambda[i] << " u " << u[i];
  EXPECT_GT(lambda.size(), size_t{50000});
}

TEST_F(PoissonTest, SmallMeansAreMonotoneInUAndBounded) {
  uint32_t max_k = 0;
  for (uint32_t q = 0; q < PoissonTable::kSmallQ8; ++q) {
    max_k = std::max(max_k, table_.Sample(q, 0xFFFFFFFFu, 0));
  }
  // Bounds derived in doubles at the largest small mean, 3071/256, and the
  // largest u, 1 - 2^-32: the exact inverse transform gives 39 (the Poisson
  // tail beyond 39 is 1.5e-10 < 2^-32); the loop stops by 48 at the latest
  // (p_49 * 2^(32 + 17) rounds to 0). The table gives 43, the bound random.h
  // states: its p_0 is exact to about 2^-31, which moves the CDF's last 2^-32
  // by a few counts. The cap kMaxSmallCount never binds.
  EXPECT_GE(max_k, 39u);
  EXPECT_LE(max_k, 48u);
  EXPECT_EQ(max_k, 43u);
  EXPECT_LT(max_k, PoissonTable::kMaxSmallCount);
  for (uint32_t q : {5u, 1000u, 3071u}) {
    uint32_t prev = 0;
    for (uint64_t u = 0; u < (uint64_t{1} << 32); u += 65537) {
      const uint32_t k = table_.Sample(q, static_cast<uint32_t>(u), 0);
      ASSERT_GE(k, prev) << q << " " << u;
      prev = k;
    }
  }
}

TEST_F(PoissonTest, LargeMeansSaturateAndNeverOverflow) {
  // lambda = 2^24 - 1/256: round(lambda + (0 - 1)/6) = 2^24.
  EXPECT_EQ(table_.Sample(0xFFFFFFFFu, 0, 0), 16777216u);
  // Extreme z: n = lambda + sigma z + (z^2 - 1)/6 with z = +-32768.
  EXPECT_EQ(table_.Sample(0xFFFFFFFFu, 0, INT32_MAX), 329951913u);
  EXPECT_EQ(table_.Sample(0xFFFFFFFFu, 0, INT32_MIN), 61516459u);
  EXPECT_EQ(table_.Sample(PoissonTable::kSmallQ8, 0, INT32_MIN), 178844130u);
  // Clamped at 0: lambda = 12, z = -5.5 gives 12 - 5.5 * 3.44 + 29.25/6 = -2.07.
  EXPECT_EQ(table_.Sample(PoissonTable::kSmallQ8, 0, -5 * 65536 - 32768), 0u);
  // Non-decreasing in z over the table's range.
  for (uint32_t q : {PoissonTable::kSmallQ8, 10240u, 0xFFFFFFFFu}) {
    uint32_t prev = 0;
    for (int32_t z = -415364; z <= 415364; z += 97) {
      const uint32_t n = table_.Sample(q, 0, z);
      ASSERT_GE(n, prev) << q << " " << z;
      prev = n;
    }
  }
}

// SigmaLanes (the sensor's block of sigmas) against Sigma, and Sample with
// a given sigma against Sample: a stride through every lambda_q8, the edges
// of the normal branch and of every power of two.
TEST_F(PoissonTest, SigmaLanesMatchSigma) {
  CAMSIM_SKIP_WITHOUT_LANE_KERNELS();
  std::vector<uint32_t> lambda;
  for (uint64_t q = 0; q <= 0xFFFFFFFFu; q += 40009) lambda.push_back(static_cast<uint32_t>(q));
  for (int b = 0; b < 32; ++b)
    for (uint32_t d : {0u, 1u, 2u}) lambda.push_back((1u << b) + d - 1);
  for (uint32_t q = PoissonTable::kSmallQ8 - 3; q < PoissonTable::kSmallQ8 + 3; ++q) lambda.push_back(q);
  lambda.push_back(0xFFFFFFFFu);
  std::vector<uint32_t> sigma(lambda.size());
  PoissonTable::SigmaLanes(lambda.data(), sigma.data(), static_cast<int>(lambda.size()));
  for (size_t i = 0; i < lambda.size(); ++i) {
    ASSERT_EQ(sigma[i], PoissonTable::Sigma(lambda[i])) << lambda[i];
    const int32_t z = static_cast<int32_t>(i * 2654435761u);
    ASSERT_EQ(table_.Sample(lambda[i], static_cast<uint32_t>(i), z, sigma[i]),
              table_.Sample(lambda[i], static_cast<uint32_t>(i), z)) << lambda[i];
  }
}

// Mean, variance and P(0) over 2^20 draws for each lambda, within 5 standard
// errors: mean sqrt(lambda/N), variance sqrt((2 lambda^2 + lambda)/N), P(0)
// sqrt(p(1-p)/N). lambda is the Q24.8 value actually used.
TEST_F(PoissonTest, MomentsMatchPoisson) {
  constexpr int kN = 1 << 20;
  for (const double lambda_in : {0.0, 0.01, 0.5, 3.0, 11.99, 12.0, 40.0, 1000.0, 1e5, 1e6}) {
    const uint32_t q = static_cast<uint32_t>(lambda_in * 256.0 + 0.5);
    const double lambda = q / 256.0;
    double sum = 0, sum2 = 0;
    int zeros = 0;
    for (uint32_t i = 0; i < kN; ++i) {
      const double k = Draw(q, i & 1023, i >> 10);
      sum += k;
      sum2 += k * k;
      zeros += k == 0;
    }
    const double mean = sum / kN;
    const double var = sum2 / kN - mean * mean;
    EXPECT_LE(std::fabs(mean - lambda), 5.0 * std::sqrt(lambda / kN)) << lambda;
    EXPECT_LE(std::fabs(var - lambda), 5.0 * std::sqrt((2 * lambda * lambda + lambda) / kN))
        << lambda;
    if (lambda < 12.0) {
      const double p0 = std::exp(-lambda);
      EXPECT_LE(std::fabs(zeros / double{kN} - p0), 5.0 * std::sqrt(p0 * (1 - p0) / kN) + 1e-12)
          << lambda;
    }
  }
}

// The sampler against a plain transcription of its definition (the original
// code: a 64-bit division per step, the bit-by-bit square root): equal for
// every small lambda_q8 at many u, and for large means over a grid of z.
uint32_t ReferenceSmall(const std::vector<uint32_t>& table, uint32_t lambda_q8, uint32_t u) {
  const uint32_t n = (lambda_q8 * 369u) >> 16;
  const uint64_t target = static_cast<uint64_t>(u) << n;
  uint64_t p = table[lambda_q8];
  uint64_t cdf = p;
  uint32_t k = 0;
  while (target >= cdf && k < PoissonTable::kMaxSmallCount) {
    const uint64_t div = static_cast<uint64_t>(k + 1) << 8;
    p = (p * lambda_q8 + div / 2) / div;
    if (p == 0) break;
    ++k;
    cdf += p;
  }
  return k;
}

uint32_t ReferenceLarge(uint32_t lambda_q8, int32_t z_q16) {
  const uint64_t lambda = static_cast<uint64_t>(lambda_q8) << 24;
  const int64_t sigma = ISqrt64BitByBit(lambda - PoissonTable::kVarianceCorrection);
  const int64_t z = z_q16;
  return SatU32(RoundShift(static_cast<int64_t>(lambda) + sigma * z + (z * z - (int64_t{1} << 32)) / 6, 32));
}

TEST_F(PoissonTest, MatchesReferenceDefinition) {
  for (uint32_t q = 0; q < PoissonTable::kSmallQ8; ++q) {
    for (uint32_t j = 0; j < 64; ++j) {
      const uint32_t u = j * 0x04000000u + q * 2654435761u % 0x04000000u;  // every 1/64 of [0, 2^32)
      ASSERT_EQ(table_.Sample(q, u, 0), ReferenceSmall(storage_, q, u)) << q << " " << u;
    }
    ASSERT_EQ(table_.Sample(q, 0xFFFFFFFFu, 0), ReferenceSmall(storage_, q, 0xFFFFFFFFu)) << q;
  }
  for (uint64_t q = PoissonTable::kSmallQ8; q <= 0xFFFFFFFFu; q += (q >> 6) + 1) {
    for (int32_t z : {INT32_MIN, -415364, -65536, -1, 0, 1, 40000, 415364, INT32_MAX}) {
      const uint32_t q32 = static_cast<uint32_t>(q);
      ASSERT_EQ(table_.Sample(q32, 0, z), ReferenceLarge(q32, z)) << q << " " << z;
    }
  }
}

TEST_F(PoissonTest, GoldenHash) {
  const uint32_t lambdas[] = {0, 3, 128, 768, 3069, 3072, 10240, 256000, 25600000, 0xFFFFFFFFu};
  Fnv1a h;
  for (uint32_t x = 0; x < 4096; ++x) h.Add(Draw(lambdas[x % 10], x, 1));
  EXPECT_EQ(h.value(), 3289604506894838876ull);  // regenerate as for the Gaussian hash
}

}  // namespace
}  // namespace camsim
