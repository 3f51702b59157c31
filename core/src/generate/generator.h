// Internal: what the generator's stages share (PRNG, bookkeeping, geometry helpers, the plant
// unit under construction). Not part of the public API; see plantview/generate.h.
//
// Coordinates here are unit-local doubles (metres; x along the unit, y across, z up, grade z = 0);
// ObjectBuilder turns them into an object origin (model space) and float offsets from it.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "plantview/generate.h"
#include "plantview/model.h"

namespace plantview::gen {

using glm::dvec3;

// ---------------------------------------------------------------------------------------------
// Directions (unit-local: x along the unit, y across, z up) and angles every stage builds with.
// Angles are float literals of the shapes' float fields, so that no stage computes them.

inline constexpr dvec3 kUp(0, 0, 1), kDown(0, 0, -1), kX(1, 0, 0), kY(0, 1, 0);
inline constexpr float kQuarterPi = 0.7853982f;  // 45 degrees
inline constexpr float kQuarterTurn = 1.5707964f;
inline constexpr float kHalfTurn = 3.1415927f;
inline constexpr float kThreeQuarterTurn = 4.712389f;
inline constexpr float kFullTurn = 6.2831855f;

// ---------------------------------------------------------------------------------------------
// PRNG: xoshiro256** seeded through splitmix64. Integer draws only; doubles come from 53 bits.

uint64_t splitmix64(uint64_t& state);
uint64_t mix_seed(uint64_t a, uint64_t b);  // a well-mixed combination of two values

class Rng {
 public:
  explicit Rng(uint64_t seed);
  uint64_t next();
  uint32_t below(uint32_t n);  // uniform in [0, n); n > 0
  int range(int lo, int hi);   // uniform in [lo, hi]
  bool chance(uint32_t per_mille) { return below(1000) < per_mille; }
  double unit() { return double(next() >> 11) * 0x1.0p-53; }                   // [0, 1)
  double metres(int lo_mm, int hi_mm) { return 0.001 * range(lo_mm, hi_mm); }  // mm grid
  template <class T>
  void shuffle(std::vector<T>& v) {
    for (size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[below(uint32_t(i))]);
  }

 private:
  uint64_t s_[4];
};

// ---------------------------------------------------------------------------------------------
// Bookkeeping: counts the generator steers toward the paper figures. Kinds follow Zhou et al.
// (snouts split into sheared cylinders, eccentric and concentric cones; pyramids are wedges).

enum Tally : uint8_t {
  kBox,
  kWedge,
  kPrism,
  kCylinder,
  kSheared,
  kEccentric,
  kConcentric,
  kTorus,
  kRectTorus,
  kSphere,
  kSaddle,
  kDish,
  kOtherKind,
  kPipes,
  kComponents,
  kComponentPrims,
  kTallyCount
};
inline constexpr int kKindTallies = kOtherKind + 1;
Tally tally_of(const Primitive& primitive);

// A contribution: how many of each tally something adds.
struct Mix {
  std::array<int32_t, kTallyCount> n{};
  Mix& add(Tally t, int32_t count = 1) {
    n[t] += count;
    return *this;
  }
  Mix& operator+=(const Mix& o) {
    for (int i = 0; i < kTallyCount; ++i) n[i] += o.n[i];
    return *this;
  }
};
Mix mix_of(const Object& object);  // kinds of its primitives; pipes/components/prims by class

// Targets and running counts of the piping stage. choose() picks the option whose mix brings the
// counts closest (least relative squared deficit) to the targets scaled by progress done/total.
// Integer arithmetic throughout, so that choices are identical on every machine.
class Ledger {
 public:
  void set_target(Tally t, int64_t value) { target_[t] = value < 0 ? 0 : value; }
  // What a deviation is measured against (default: the target): the plant-wide figure when the
  // target is only this stage's share of it.
  void set_scale(Tally t, int64_t value) { scale_[t] = value; }
  int64_t target(Tally t) const { return target_[t]; }
  int64_t count(Tally t) const { return count_[t]; }
  void add(const Mix& mix);
  void set_progress(uint64_t done, uint64_t total) {
    done_ = done;
    total_ = total == 0 ? 1 : total;
  }
  // Index of the best option (the first on ties). Options must not be empty.
  size_t choose(std::span<const Mix> options) const;
  // Whether adding `mix` now brings the counts closer to the targets than adding nothing.
  bool wants(const Mix& mix) const;
  // Whether `n` more of tally `t` stay within its target.
  bool room(Tally t, int64_t n) const { return count_[t] + n <= target_[t]; }

 private:
  __extension__ typedef __int128 Wide;
  double gain(const Mix& mix) const;
  std::array<int64_t, kTallyCount> target_{}, count_{}, scale_{};
  uint64_t done_ = 0, total_ = 1;
};

// ---------------------------------------------------------------------------------------------
// Pipe sizes (ASME B36.10 outside diameters, class 150 flanges, long-radius elbows).

struct PipeSize {
  const char* label;    // "6\"" for the reader
  int dn;               // DN (mm)
  double od_m;          // pipe outside diameter
  double flange_od_m;   // flange outside diameter
  double flange_thk_m;  // flange length along the run (hub included)
  double valve_len_m;   // gate valve face to face
  double elbow_r_m;     // long-radius bend radius: 1.5 x NPS
};
inline constexpr int kPipeSizeCount = 20;
extern const std::array<PipeSize, kPipeSizeCount> kPipeSizes;
inline const PipeSize& pipe_size(int bore) { return kPipeSizes[size_t(bore)]; }
int bore_at_least(double od_m);  // smallest bore index whose OD >= od_m (the largest if none)

// ---------------------------------------------------------------------------------------------
// Geometry helpers.

// A right-handed rotation whose local z is `z_axis` (unit). Local x is horizontal where possible.
glm::mat3 frame_z(const dvec3& z_axis);
// A right-handed rotation with local x = x_axis and local z = z_axis (both unit, orthogonal).
glm::mat3 frame_xz(const dvec3& x_axis, const dvec3& z_axis);
// A unit vector perpendicular to the unit vector `d`, as close to up (+z) as it can be.
dvec3 perpendicular_up(const dvec3& d);

// Builds one object: primitives are given in unit-local coordinates and stored relative to the
// object's origin. All lengths in metres.
class ObjectBuilder {
 public:
  ObjectBuilder(const dvec3& unit_origin_m, const dvec3& local_origin, ObjectClass object_class);
  Object& object() { return object_; }
  const dvec3& local_origin() const { return local_origin_; }
  glm::vec3 rel(const dvec3& p) const { return glm::vec3(p - local_origin_); }

  void add(const Shape& shape, const glm::mat3& linear, const dvec3& centre);
  void cylinder(const dvec3& a, const dvec3& b, double radius);  // axis from a to b
  // Snout from a (radius ra) to b (radius rb) along `axis`; b - a may have a lateral part (offset).
  void snout(const dvec3& a, const dvec3& b, double ra, double rb, const dvec3& axis);
  // Cylinder from a to b whose end planes are tilted: shear angles (rad) about local y, where
  // local x is `tilt_toward` (unit, perpendicular to the axis).
  void sheared_cylinder(const dvec3& a, const dvec3& b, double radius, const dvec3& tilt_toward,
                        float bottom_shear_rad, float top_shear_rad);
  void box(const dvec3& centre, const dvec3& x_axis, const dvec3& z_axis, const dvec3& size);
  void box_axes(const dvec3& min_corner, const dvec3& max_corner);  // axis-aligned
  // Wedge: a box's bottom face (size x by y) rising to an edge along local y at +x side over
  // `height`; z_axis the rising direction, x_axis toward where the wedge is tall.
  void wedge(const dvec3& base_centre, const dvec3& x_axis, const dvec3& z_axis, double size_x,
             double size_y, double height);
  void prism(const dvec3& base_centre, const dvec3& axis, uint32_t sides, double radius,
             double height);
  void sphere(const dvec3& centre, double radius);
  // Elliptical head standing on base_centre, rising along `axis` to `height`.
  void dish(const dvec3& base_centre, const dvec3& axis, double base_radius, double height);
  // A 90 degree elbow: flow arrives along d_in at the corner (where the two run centrelines
  // meet) and leaves along d_out (perpendicular); the bend runs from corner - r*d_in to
  // corner + r*d_out.
  void elbow(const dvec3& corner, const dvec3& d_in, const dvec3& d_out, double bend_r,
             double tube_r);
  void rect_torus(const dvec3& centre, const dvec3& axis, const dvec3& start_dir, double inner_r,
                  double outer_r, double height, float angle_rad);
  // Saddle on grade under a horizontal vessel of axis `vessel_axis` (x of the saddle).
  void saddle(const dvec3& base_centre, const dvec3& vessel_axis, double length, double width,
              double height, double cradle_radius);

  void attribute(std::string_view key, std::string value) {
    object_.attributes.push_back({std::string(key), std::move(value)});
  }
  void connection(const dvec3& position, const dvec3& direction, double diameter);
  void centreline(const dvec3& a, const dvec3& b, double diameter);

 private:
  Object object_;
  dvec3 local_origin_;
};

std::string fixed(double value, int decimals);  // "12.35": locale-independent

// ---------------------------------------------------------------------------------------------
// The plant unit under construction.

// An equipment nozzle: a flanged end that a pipeline may connect to.
// Spare nozzles stay unconnected (blinded on the equipment).
enum class NozzleRole : uint8_t {
  process,
  outlet_bottom,
  top,
  pump_suction,
  pump_discharge,
  utility,
  spare
};
struct Nozzle {
  dvec3 position;   // flange face centre (unit-local)
  dvec3 direction;  // outward, axis-aligned unit
  int bore = 0;
  NozzleRole role = NozzleRole::process;
  bool flanged = true;     // else a bevelled end for a butt weld
  uint32_t equipment = 0;  // index into Unit::equipment
  bool used = false;
};

enum class EquipmentType : uint8_t {
  column,
  vertical_drum,
  horizontal_drum,
  exchanger,
  pump,
  compressor,
  air_cooler,
  furnace,
  filter,
  tank,
  sphere_tank,
  package,
};
inline constexpr int kEquipmentTypeCount = 12;

struct EquipmentRecord {
  EquipmentType type = EquipmentType::package;
  std::string tag;                              // "C-01-004"
  std::string description;                      // "Depropanizer"
  dvec3 centre{0.0};                            // footprint centre on grade
  double size_x = 0, size_y = 0;                // footprint
  double diameter = 0, length = 0, height = 0;  // main body
  int band = -1;                                // layout band index (-1: on a rack)
  int feeds_pair = -1;                          // vessels: the pump pair their bottom outlet feeds
  int pump_pair = -1;                           // pumps: their pair
  char pump_letter = 0;                         // 'A' or 'B'
  int pump_bore = 0;                            // pumps: suction bore, the same for both of a pair
  bool on_saddles = false;                      // exchangers
  double elevation = 0;                         // stacked exchangers: the lower shell's top
  int stacked_on = -1;                          // stacked exchangers: the equipment below
  std::vector<uint32_t> nozzles;
};

struct Rack {
  double y_centre = 0, width = 0, x_begin = 0, x_end = 0, bent_pitch = 6;
  std::vector<double> tiers;  // beam top elevations
  // Lane occupancy per tier: lanes across the width, each a list of used x intervals.
  std::vector<std::vector<std::vector<std::pair<double, double>>>> lanes;
  double lane_pitch = 0.6;
};

// A strip beside a rack where equipment stands: y from `y_near` (rack side) to `y_far`.
struct Band {
  int rack = 0;
  int side = 1;  // +1: band at larger y than its rack, -1: smaller
  double y_near = 0, y_far = 0;
  double pump_row_y = 0;  // pump shaft-centre line (y)
  // A shelf is a row of columns; a column holds items one behind the other (across y).
  struct Column {
    double x0, width, used;  // start x, width along x, depth used from the shelf's start
  };
  struct Shelf {
    double next_x, start, depth;  // next free x; distance beyond the pump row; depth across
    std::vector<Column> columns;
    std::vector<uint32_t> items;  // equipment indices
  };
  std::vector<Shelf> shelves;
  std::vector<std::pair<double, double>> pump_slots;  // x intervals used in the pump row
};

struct PresetSpec;  // presets.cpp

class Emitter {
 public:
  Emitter(const std::function<void(Object&&)>& sink, GenerateSummary& summary)
      : sink_(sink), summary_(summary) {}
  void emit(Object&& object);

 private:
  const std::function<void(Object&&)>& sink_;
  GenerateSummary& summary_;
};

struct Unit {
  Unit(const PresetSpec& spec_, const PresetInfo& info_, uint32_t index_, uint64_t seed,
       Emitter& out_)
      : spec(spec_), info(info_), index(index_), rng(seed), out(out_) {}
  const PresetSpec& spec;
  const PresetInfo& info;
  uint32_t index = 0;
  std::string area;       // "01"
  std::string id_source;  // "gen:c:1:0"
  std::string source;     // "gen:c"
  dvec3 origin_m{0.0};    // model-space position of the unit's (0, 0, 0)
  Rng rng;
  Emitter& out;
  Ledger ledger;         // piping stage targets
  Ledger detail_ledger;  // equipment details: keeps their kinds in proportion to the plant's
  std::vector<Rack> racks;
  std::vector<Band> bands;
  std::vector<EquipmentRecord> equipment;
  std::vector<Nozzle> nozzles;
  Mix emitted;                                       // everything emitted so far in this unit
  std::array<int64_t, kKindTallies> kind_targets{};  // Zhou's kinds for this unit
  std::array<int64_t, kObjectClassCount> primitives_by_class{}, objects_by_class{};
  bool piping = false;             // the piping stage runs: emitted objects count in the ledger
  uint32_t pipelines_skipped = 0;  // planned but not routable

  uint64_t id(std::string_view name) const { return object_id(id_source, name); }
  // Finishes and emits an object: name, id, source.
  void emit(ObjectBuilder& builder, std::string name);
};

// Stages, in the order generate_plant runs them for each unit.
void lay_out_unit(Unit& unit);     // layout.cpp: racks, bands
void build_equipment(Unit& unit);  // equipment.h: places and emits equipment, lists nozzles
void build_structure(Unit& unit);  // structure.cpp: racks and steel structures
void build_piping(Unit& unit, const std::function<void(double)>& progress);  // pipelines.h

// Layout services (layout.cpp). Reserves a footprint (x by y) in a band's shelves; returns false
// when the band is full. `centre` receives the footprint centre on grade.
// `item` is recorded on the shelf. With `overflow`, a full band opens a shelf beyond its far
// edge instead of failing (the plot grows rather than items overlapping).
bool place_in_band(Unit& unit, int band, double size_x, double size_y, uint32_t item, bool overflow,
                   dvec3& centre);
// Spreads each shelf's items evenly along the rack instead of leaving them packed at its start.
void spread_shelves(Unit& unit);
// Reserves size_x along the band's pump row as close to x_wanted as it can; false when full.
bool place_in_pump_row(Unit& unit, int band, double x_wanted, double size_x, double& x_centre);
// Forgets every shelf and pump slot (to retry a layout with smaller equipment).
void clear_band_places(Unit& unit);
// Reserves a rack lane for a run from x0 to x1 at tier `tier`, searching from the rack's low-y
// edge (from_side < 0) or high-y edge (> 0); returns the lane's y, or NAN when the tier is full.
double reserve_lane(Rack& rack, int tier, double x0, double x1, double od_m, int from_side);
// x of the rack's bents.
inline double bent_x(const Rack& rack, int i) { return rack.x_begin + rack.bent_pitch * i; }

}  // namespace plantview::gen
