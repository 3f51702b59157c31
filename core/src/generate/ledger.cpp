// Bookkeeping: the PRNG, the tallies of what was generated, and the ledger that steers choices
// toward the papers' figures.
#include <algorithm>
#include <cassert>

#include "generator.h"

namespace plantview::gen {

uint64_t splitmix64(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

uint64_t mix_seed(uint64_t a, uint64_t b) {
  uint64_t s = a ^ (b * 0xd1b54a32d192ed03ull);
  splitmix64(s);
  return splitmix64(s);
}

Rng::Rng(uint64_t seed) {
  uint64_t s = seed;
  for (uint64_t& w : s_) w = splitmix64(s);
}

uint64_t Rng::next() {
  auto rotl = [](uint64_t x, int k) { return (x << k) | (x >> (64 - k)); };
  const uint64_t result = rotl(s_[1] * 5, 7) * 9;
  const uint64_t t = s_[1] << 17;
  s_[2] ^= s_[0];
  s_[3] ^= s_[1];
  s_[1] ^= s_[2];
  s_[0] ^= s_[3];
  s_[2] ^= t;
  s_[3] = rotl(s_[3], 45);
  return result;
}

uint32_t Rng::below(uint32_t n) {
  assert(n > 0);
  // Lemire's multiply-shift; the tiny bias is irrelevant here and the result is deterministic.
  return uint32_t((uint64_t(uint32_t(next() >> 32)) * n) >> 32);
}

int Rng::range(int lo, int hi) {
  if (hi <= lo) return lo;
  return lo + int(below(uint32_t(hi - lo + 1)));
}

Tally tally_of(const Primitive& p) {
  switch (p.kind()) {
    case PrimitiveKind::box:
      return kBox;
    case PrimitiveKind::pyramid:
      return kWedge;
    case PrimitiveKind::prism:
      return kPrism;
    case PrimitiveKind::cylinder:
      return kCylinder;
    case PrimitiveKind::snout:
      switch (snout_variant(std::get<Snout>(p.shape))) {
        case SnoutVariant::sheared_cylinder:
          return kSheared;
        case SnoutVariant::eccentric_cone:
          return kEccentric;
        case SnoutVariant::concentric_cone:
          return kConcentric;
      }
      return kConcentric;
    case PrimitiveKind::circular_torus:
      return kTorus;
    case PrimitiveKind::rectangular_torus:
      return kRectTorus;
    case PrimitiveKind::sphere:
      return kSphere;
    case PrimitiveKind::saddle:
      return kSaddle;
    case PrimitiveKind::elliptical_dish:
      return kDish;
    default:
      return kOtherKind;
  }
}

Mix mix_of(const Object& object) {
  Mix m;
  for (const Primitive& p : object.primitives) m.add(tally_of(p));
  if (object.object_class == ObjectClass::pipe) m.add(kPipes);
  if (object.object_class == ObjectClass::component) {
    m.add(kComponents);
    m.add(kComponentPrims, int32_t(object.primitives.size()));
  }
  return m;
}

void Ledger::add(const Mix& mix) {
  for (int i = 0; i < kTallyCount; ++i) count_[i] += mix.n[i];
}

// Reduction of sum_k cost((expected_k - count_k) / scale_k) when `mix` is added, where
// expected_k = target_k * done / total, scale_k is the target unless set, and cost(x) = x^2,
// more when x < 0 (being over a target is worse than being under it: later choices can add, never
// remove; small counts cannot absorb overshoot at all). The differences are exact integers (in
// units of 1/total); each term is then one correctly rounded division, summed in a fixed order,
// so that the result is the same on every machine.
double Ledger::gain(const Mix& mix) const {
  double sum = 0.0;
  const Wide total = Wide(total_);
  for (int k = 0; k < kTallyCount; ++k) {
    if (mix.n[k] == 0) continue;
    const int64_t scale = scale_[k] > 0 ? scale_[k] : std::max<int64_t>(target_[k], 1);
    const Wide over = scale < 500 ? 8 : 2;
    auto cost = [over](Wide x) { return x >= 0 ? x * x : over * x * x; };
    const Wide deficit = Wide(target_[k]) * Wide(done_) - Wide(count_[k]) * total;
    const Wide c = Wide(mix.n[k]) * total;
    const double t = double(scale) * double(total_);
    sum += double(cost(deficit) - cost(deficit - c)) / (t * t);
  }
  return sum;
}

size_t Ledger::choose(std::span<const Mix> options) const {
  assert(!options.empty());
  size_t best = 0;
  double best_gain = gain(options[0]);
  for (size_t i = 1; i < options.size(); ++i) {
    const double g = gain(options[i]);
    if (g > best_gain) {
      best_gain = g;
      best = i;
    }
  }
  return best;
}

bool Ledger::wants(const Mix& mix) const { return gain(mix) > 0; }

}  // namespace plantview::gen
