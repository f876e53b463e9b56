// The index finds the smallest energy and every model of that energy, as scoring every model
// does, and scores few of many models: random catalogs (families of one profile in sizes around
// a base, as a catalog grown by scaled and stretched variants), random objects, an energy of
// size penalties, a profile distance and a further scalar.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "catalog_index/catalog_index.hpp"

namespace {

using namespace furnihost::catalog_index;
constexpr int kBins = 20;

float Emd(const std::vector<float>& a, const std::vector<float>& b) {
  float ca = 0, cb = 0, d = 0;
  for (int i = 0; i < kBins; ++i) ca += a[size_t(i)], cb += b[size_t(i)], d += std::abs(ca - cb);
  return d / kBins;
}
float Pen(float d, float s) { return d * d / (2 * s * s); }

struct Object {
  std::array<float, 3> size;
  float extra;
  std::vector<float> hist, cdf;
};

std::vector<float> RandomHistogram(std::mt19937_64& rng) {
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<float> h(kBins);
  float s = 0;
  for (auto& v : h) s += v = u(rng) * u(rng) * u(rng);
  for (auto& v : h) v /= s;
  return h;
}

TEST(CatalogIndex, FindsTheBestOfEveryModelAndScoresFew) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<Item> items;
  for (int family = 0; family < 60; ++family) {
    const std::vector<float> h = RandomHistogram(rng), view = RandomHistogram(rng);
    const std::array<float, 3> base = {0.4f + 1.5f * u(rng), 0.4f + 0.8f * u(rng), 0.4f + 1.4f * u(rng)};
    for (int v = 0; v < 100; ++v) {  // scaled and stretched variants
      Item it;
      for (int a = 0; a < 3; ++a) it.size[size_t(a)] = base[size_t(a)] * (0.8f + 0.45f * u(rng));
      it.extra = u(rng);
      it.histograms = {h, view};
      items.push_back(it);
    }
  }
  const Index index(items, kBins);
  EXPECT_EQ(index.Size(), items.size());
  size_t scored_total = 0;
  for (int q = 0; q < 300; ++q) {
    // An object like a variant of a family (most queries), or like none.
    Object o;
    const Item& like = items[size_t(rng() % items.size())];
    o.hist = q % 5 == 0 ? RandomHistogram(rng) : like.histograms[0];
    for (int a = 0; a < 3; ++a) o.size[size_t(a)] = like.size[size_t(a)] * (0.85f + 0.3f * u(rng));
    o.extra = u(rng);
    o.cdf.resize(kBins);
    Cumulative(o.hist.data(), kBins, o.cdf.data());
    auto energy = [&](const Item& it) {
      float e = 0;
      for (int a = 0; a < 3; ++a) e += Pen(std::log(o.size[size_t(a)] / it.size[size_t(a)]), 0.2f);
      const float emd = std::min(Emd(o.hist, it.histograms[0]), Emd(o.hist, it.histograms[1]));
      return e + Pen(emd, 0.05f) + Pen(o.extra - it.extra, 0.5f);
    };
    float best = INFINITY;
    std::vector<size_t> argmin;
    for (size_t i = 0; i < items.size(); ++i) {
      const float e = energy(items[i]);
      if (e < best) best = e, argmin = {i};
      else if (e == best) argmin.push_back(i);
    }
    auto bound = [&](const Bounds& b) {
      float e = 0;
      for (int a = 0; a < 3; ++a) {
        const float x = o.size[size_t(a)];
        e += Pen(std::log(x / std::clamp(x, b.size_lo[size_t(a)], b.size_hi[size_t(a)])), 0.2f);
      }
      e += Pen(EmdLowerBound(o.cdf.data(), b.any_lo, b.any_hi), 0.05f);
      e += Pen(o.extra - std::clamp(o.extra, b.extra_lo, b.extra_hi), 0.5f);
      return e * (1.f - 1e-5f) - 1e-6f;  // a margin for the rounding of the logarithms
    };
    float found = INFINITY;
    std::vector<size_t> found_at;
    const size_t scored = index.Search(bound, [&](size_t i) {
      const float e = energy(items[i]);
      if (e < found) found = e, found_at = {i};
      else if (e == found) found_at.push_back(i);
      return e;
    });
    ASSERT_EQ(found, best) << q;
    std::sort(found_at.begin(), found_at.end());
    ASSERT_EQ(found_at, argmin) << q;
    scored_total += scored;
  }
  // A few hundred of 6000 models per object on average (all of them without the index).
  EXPECT_LT(scored_total / 300, items.size() / 10);
  std::printf("scored %zu of %zu models per object on average\n", scored_total / 300, items.size());
}

TEST(CatalogIndex, EmptyAndSingleModel) {
  const Index none({}, kBins);
  EXPECT_EQ(none.Search([](const Bounds&) { return 0.f; }, [](size_t) { return 0.f; }), 0u);
  Item it;
  it.size = {1, 1, 1};
  it.histograms = {std::vector<float>(kBins, 0.05f)};
  const Index one({it}, kBins);
  size_t seen = 99;
  EXPECT_EQ(one.Search([](const Bounds&) { return 0.f; }, [&](size_t i) { return float(seen = i); }), 1u);
  EXPECT_EQ(seen, 0u);
}

// The profile bound never exceeds the distance it bounds, in float.
TEST(CatalogIndex, EmdLowerBoundBelowEveryDistance) {
  std::mt19937_64 rng(8);
  for (int t = 0; t < 2000; ++t) {
    const std::vector<float> q = RandomHistogram(rng);
    std::vector<float> qc(kBins), lo(kBins, INFINITY), hi(kBins, -INFINITY), c(kBins);
    Cumulative(q.data(), kBins, qc.data());
    std::vector<std::vector<float>> hs;
    for (int k = 0; k < 1 + t % 5; ++k) {
      hs.push_back(RandomHistogram(rng));
      Cumulative(hs.back().data(), kBins, c.data());
      for (int i = 0; i < kBins; ++i) lo[size_t(i)] = std::min(lo[size_t(i)], c[size_t(i)]), hi[size_t(i)] = std::max(hi[size_t(i)], c[size_t(i)]);
    }
    const float lb = EmdLowerBound(qc.data(), lo, hi);
    for (const auto& h : hs) ASSERT_LE(lb, Emd(q, h)) << t;
  }
}

}  // namespace
