// Internal: piping parts and the branch builder shared by piping_parts.cpp (one builder per kind
// of pipe, fitting, valve and support) and the piping stage's files (pipelines.h: planning,
// routing, branches).
#pragma once

#include <string>
#include <vector>

#include "generator.h"

namespace plantview::gen {

enum class Service : uint8_t {
  process,
  lp_steam,
  mp_steam,
  condensate,
  cooling_water_supply,
  cooling_water_return,
  nitrogen,
  instrument_air,
  plant_air,
  fuel_gas,
  flare,
};
struct ServiceInfo {
  const char* code;   // line number prefix: "P", "LS", "CWS"...
  const char* fluid;  // "Hydrocarbon", "Low pressure steam"...
  Colour colour;
};
const ServiceInfo& service_info(Service service);

// Every kind of branch member (and support). Straight members advance along the run.
enum class Part : uint8_t {
  pipe,
  elbow,
  tee,
  olet,
  weld,
  flange_so,
  flange_wn,
  gasket,
  blind,
  cap,
  plug,
  gate,
  globe,
  globe_y,
  ball,
  ball_welded,
  ball_sw,
  check,
  butterfly,
  control,
  reducer_conc,
  reducer_ecc,
  strainer,
  trap,
  orifice,
  spectacle,
  // Supports (not branch members).
  shoe,
  shoe_gusseted,
  guide,
  hanger,
  clamp,
  bracket,
  bracket_braced,
  strut,
  trunnion,
  stanchion,
  dummy_leg,
  dummy_leg_bare,
  dummy_leg_gusseted,
};
inline constexpr int kPartCount = int(Part::dummy_leg_gusseted) + 1;

// A straight member of a group, in flow order. Reducers change the bore from bore_in to bore_out
// (eccentric ones keep the top flat, shifting the axis); flanges face the joint on their outlet
// side when face_forward, else on their inlet side.
struct Item {
  Part part = Part::gasket;
  int bore_in = 0, bore_out = 0;
  bool face_forward = true;
};
inline Item item(Part part, int bore, bool face_forward = true) {
  return {part, bore, bore, face_forward};
}

double item_length(const Item& item);
// Where a member that starts at `from` on a run along `dir` ends.
dvec3 advance(const dvec3& from, const Item& item, const dvec3& dir);
// Lateral displacement of the run axis across the item (eccentric reducers only).
dvec3 item_shift(const Item& item, const dvec3& dir);
// What a part adds to the tallies (primitives by kind, one component).
const Mix& part_mix(Part part);
bool is_closure(Part part);  // blind, cap, plug: a branch ends on it

// A place a branch starts or ends: a point, the direction the flow runs there (out of a nozzle
// or tee port at a branch head, into it at a tail), and the bore.
struct Port {
  dvec3 position{0.0};
  dvec3 direction{0, 0, 1};
  int bore = 0;
};

// One pipeline under construction: names, spec, and the branches built so far.
struct LineContext {
  explicit LineContext(Unit& unit_) : unit(unit_) {}
  Unit& unit;
  std::string name;  // "/P-01-0203"
  uint64_t id = 0;
  Service service = Service::process;
  int bore = 0;  // nominal line size
  const char* spec = "A1A";
  const char* rating = "CL150";
  bool weld_neck = false;  // flange type of the spec
  int support_count = 0;
  std::vector<Branch> branches;
  std::string from, to;      // for the pipeline's attributes
  int tag_seq = 0;           // valve tags
  double bend_factor = 1.0;  // elbow bend radius over the long-radius one (1, 2 or 3.33)
};

// Builds one branch member after another: every member starts where the previous one ended.
class Run {
 public:
  Run(LineContext& line, int branch_number, const Port& head);
  const dvec3& position() const { return pos_; }
  const dvec3& direction() const { return dir_; }
  int bore() const { return bore_; }
  const std::string& name() const { return name_; }

  void straight(const Item& item);                      // a fitting, valve, flange, weld...
  void pipe_to(const dvec3& end);                       // a pipe along the current direction
  void elbow(const dvec3& corner, const dvec3& d_out);  // position must be corner - R * dir
  Port tee(const dvec3& branch_dir, int branch_bore);   // the branch port, pointing out
  // A branch outlet welded onto the run (no length along it): inlet and outlet at the same point.
  Port olet(const dvec3& branch_dir, int branch_bore);
  void weld();
  // Registers the branch with its pipeline (members in flow order).
  void finish();

  // Pipes built by this run (for supports): start, end, outside diameter.
  struct PipeSpan {
    dvec3 a, b;
    int bore;
  };
  const std::vector<PipeSpan>& pipes() const { return pipes_; }
  struct ElbowAt {
    dvec3 corner, d_in, d_out;
    int bore;
  };
  const std::vector<ElbowAt>& elbows() const { return elbows_; }

 private:
  ObjectBuilder begin(ObjectClass object_class) const;
  void emit(ObjectBuilder& b, Part part, std::string name, const char* stype = nullptr);
  std::string member_name(const char* type);

  LineContext& line_;
  std::string name_;
  std::vector<uint64_t> members_;
  std::vector<std::pair<std::string, int>> counters_;
  dvec3 pos_, dir_;
  int bore_;
  std::vector<PipeSpan> pipes_;
  std::vector<ElbowAt> elbows_;
};

// A pipe support at `at` on a pipe of `bore` running along `dir`; emitted as a component of the
// pipeline. `ground_z` is where it stands (beam top, grade) or hangs from (steel above); brackets
// reach sideways toward `toward` (horizontal, perpendicular to the pipe).
void build_support(LineContext& line, Part part, const dvec3& at, const dvec3& dir, int bore,
                   double ground_z, const dvec3& toward = dvec3(0, 0, -1));

}  // namespace plantview::gen
