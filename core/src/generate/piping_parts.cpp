// Piping parts: the shape, connection points, centreline and attributes of every kind of pipe,
// fitting, valve, flange and support, built one member after another along a branch.
#include <array>
#include <cassert>
#include <cmath>
#include <string>

#include "piping.h"

namespace plantview::gen {

namespace {

constexpr Colour kFlangeGrey{170, 170, 176, 255};
constexpr Colour kValveRed{205, 58, 48, 255};
constexpr Colour kInstrumentYellow{232, 204, 48, 255};
constexpr Colour kSupportGrey{118, 118, 124, 255};

const ServiceInfo kServices[] = {
    {"P", "Hydrocarbon", {226, 196, 78, 255}},
    {"LS", "Low pressure steam", {205, 205, 205, 255}},
    {"MS", "Medium pressure steam", {190, 190, 198, 255}},
    {"SC", "Steam condensate", {176, 176, 226, 255}},
    {"CWS", "Cooling water supply", {62, 160, 92, 255}},
    {"CWR", "Cooling water return", {44, 132, 72, 255}},
    {"N", "Nitrogen", {232, 150, 52, 255}},
    {"IA", "Instrument air", {82, 160, 220, 255}},
    {"PA", "Plant air", {104, 182, 230, 255}},
    {"FG", "Fuel gas", {220, 122, 182, 255}},
    {"FL", "Flare", {162, 112, 62, 255}},
};

struct PartInfo {
  const char* type;   // PDMS element type
  const char* stype;  // catalogue subtype
  const char* material;
};
constexpr PartInfo kParts[kPartCount] = {
    {"TUBE", "SMLS", "A106 Gr.B"},
    {"ELBO", "LR90", "A234 WPB"},
    {"TEE", "EQUAL", "A234 WPB"},
    {"OLET", "WOL", "A105"},
    {"WELD", "BW", ""},
    {"FLAN", "SO", "A105"},
    {"FLAN", "WN", "A105"},
    {"GASK", "SPW", "SS316/Graphite"},
    {"FBLI", "BL", "A105"},
    {"CAP", "ELLI", "A234 WPB"},
    {"PLUG", "HEX", "A105"},
    {"VALV", "GATE", "A216 WCB"},
    {"VALV", "GLOBE", "A216 WCB"},
    {"VALV", "Y-GLOBE", "A216 WCB"},
    {"VALV", "BALL", "A216 WCB"},
    {"VALV", "BALL BW", "A216 WCB"},
    {"VALV", "BALL SW", "A105"},
    {"VALV", "SWING CHECK", "A216 WCB"},
    {"VALV", "BUTTERFLY", "A216 WCB"},
    {"INST", "GLOBE CV", "A216 WCB"},
    {"REDU", "CONC", "A234 WPB"},
    {"REDU", "ECC", "A234 WPB"},
    {"FILT", "Y-TYPE", "A216 WCB"},
    {"TRAP", "FLOAT", "A216 WCB"},
    {"INST", "ORIFICE PLATE", "SS316"},
    {"PCOM", "SPECTACLE", "A516 Gr.70"},
    {"SUPP", "SHOE", "S275"},
    {"SUPP", "SHOE", "S275"},
    {"SUPP", "GUIDE", "S275"},
    {"SUPP", "ROD HANGER", "S275"},
    {"SUPP", "RISER CLAMP", "S275"},
    {"SUPP", "BRACKET", "S275"},
    {"SUPP", "BRACED BRACKET", "S275"},
    {"SUPP", "STRUT", "S275"},
    {"SUPP", "TRUNNION", "S275"},
    {"SUPP", "STANCHION", "S275"},
    {"SUPP", "DUMMY LEG", "S275"},
    {"SUPP", "DUMMY LEG", "S275"},
    {"SUPP", "DUMMY LEG", "S275"},
};

std::array<Mix, kPartCount> make_part_mixes() {
  std::array<Mix, kPartCount> m{};
  auto set = [&](Part p, std::initializer_list<std::pair<Tally, int>> kinds) {
    Mix& x = m[size_t(p)];
    int prims = 0;
    for (auto [t, n] : kinds) {
      x.add(t, n);
      prims += n;
    }
    if (p == Part::pipe) {
      x.add(kPipes);
    } else {
      x.add(kComponents);
      x.add(kComponentPrims, prims);
    }
  };
  set(Part::pipe, {{kCylinder, 1}});
  set(Part::elbow, {{kTorus, 1}});
  set(Part::tee, {{kCylinder, 2}});
  set(Part::olet, {{kSheared, 1}});
  set(Part::weld, {});
  set(Part::flange_so, {{kCylinder, 1}});
  set(Part::flange_wn, {{kCylinder, 1}, {kConcentric, 1}});
  set(Part::gasket, {{kCylinder, 1}});
  set(Part::blind, {{kCylinder, 1}});
  set(Part::cap, {{kDish, 1}});
  set(Part::plug, {{kPrism, 1}});
  set(Part::gate, {{kConcentric, 2}, {kCylinder, 2}});
  set(Part::globe, {{kSphere, 1}, {kCylinder, 4}});
  set(Part::globe_y, {{kCylinder, 4}, {kSheared, 1}});
  set(Part::ball, {{kSphere, 1}, {kCylinder, 2}, {kBox, 1}});
  set(Part::ball_welded, {{kSphere, 1}, {kConcentric, 2}});
  set(Part::ball_sw, {{kSphere, 1}});
  set(Part::check, {{kConcentric, 2}, {kSheared, 1}});
  set(Part::butterfly, {{kCylinder, 2}, {kBox, 1}});
  set(Part::control, {{kSphere, 1}, {kCylinder, 3}, {kConcentric, 2}});
  set(Part::reducer_conc, {{kConcentric, 1}});
  set(Part::reducer_ecc, {{kEccentric, 1}});
  set(Part::strainer, {{kCylinder, 2}, {kSheared, 1}});
  set(Part::trap, {{kSphere, 1}});
  set(Part::orifice, {{kCylinder, 3}});
  set(Part::spectacle, {{kCylinder, 2}, {kBox, 1}});
  set(Part::shoe, {{kBox, 2}});
  set(Part::shoe_gusseted, {{kBox, 2}, {kWedge, 2}});
  set(Part::guide, {{kBox, 4}});
  set(Part::hanger, {{kRectTorus, 1}, {kCylinder, 1}, {kBox, 1}});
  set(Part::bracket, {{kBox, 1}, {kSheared, 1}});
  set(Part::bracket_braced, {{kBox, 1}, {kSheared, 2}});
  set(Part::trunnion, {{kSheared, 1}, {kBox, 1}});
  set(Part::strut, {{kSheared, 1}});
  set(Part::clamp, {{kRectTorus, 1}});
  set(Part::stanchion, {{kCylinder, 1}, {kBox, 2}});
  set(Part::dummy_leg, {{kSheared, 1}, {kBox, 1}});
  set(Part::dummy_leg_bare, {{kSheared, 1}});
  set(Part::dummy_leg_gusseted, {{kSheared, 1}, {kBox, 1}, {kWedge, 2}});
  return m;
}
const std::array<Mix, kPartCount> kPartMixes = make_part_mixes();

double tee_half(int bore) { return 0.025 + 0.72 * pipe_size(bore).od_m; }

const std::string& bore_text(int bore) {
  static const std::array<std::string, kPipeSizeCount> texts = [] {
    std::array<std::string, kPipeSizeCount> t;
    for (int i = 0; i < kPipeSizeCount; ++i) {
      const PipeSize& s = pipe_size(i);
      t[size_t(i)] = "DN" + std::to_string(s.dn) + " (" + s.label + ")";
    }
    return t;
  }();
  return texts[size_t(bore)];
}

// A unit vector across the run, horizontal where the run is (up where it is vertical... any
// perpendicular otherwise): stems and levers point up, strainer screens down.
dvec3 stem_direction(const dvec3& dir) { return perpendicular_up(dir); }

// Adds the part's primitives for a member from `a` along `dir`; returns the outlet point.
dvec3 shape_item(ObjectBuilder& b, const Item& it, const dvec3& a, const dvec3& dir) {
  const PipeSize& s = pipe_size(it.bore_in);
  const double r = 0.5 * s.od_m, rf = 0.5 * s.flange_od_m;
  const double len = item_length(it);
  const dvec3 out = advance(a, it, dir);
  const dvec3 m = a + dir * (0.5 * len);
  const dvec3 up = stem_direction(dir);
  // Stem and handwheel (a disc, as simplified valve catalogues draw it).
  auto handwheel = [&](const dvec3& stem_from, const dvec3& stem_dir, double stem_len) {
    const dvec3 top = stem_from + stem_dir * stem_len;
    b.cylinder(stem_from, top, std::max(0.012, 0.08 * s.od_m));
    b.cylinder(top, top + stem_dir * 0.03, 0.6 * s.od_m + 0.07);
  };
  switch (it.part) {
    case Part::flange_so:
      b.cylinder(a, out, rf);
      break;
    case Part::flange_wn: {
      // Hub on the pipe side, disc on the joint side.
      const dvec3 face = it.face_forward ? out : a, pipe_end = it.face_forward ? a : out;
      const dvec3 disc_end = face + (pipe_end - face) * 0.4;
      b.cylinder(face, disc_end, rf);
      b.snout(pipe_end, disc_end, r, std::min(rf * 0.9, 1.35 * r),
              glm::normalize(disc_end - pipe_end));
      break;
    }
    case Part::gasket:
      b.cylinder(a, out, 0.5 * (r + rf));
      break;
    case Part::blind:
      b.cylinder(a, out, rf);
      break;
    case Part::cap:
      b.dish(a, dir, r, 0.5 * r);
      break;
    case Part::plug:
      b.prism(a, dir, 6, 1.15 * r, len);
      break;
    case Part::gate:
      b.snout(a, m, 0.9 * rf, 0.75 * r, dir);
      b.snout(m, out, 0.75 * r, 0.9 * rf, dir);
      handwheel(m, up, 1.6 * s.od_m + 0.25);
      break;
    case Part::globe:
      b.cylinder(a, a + dir * (0.25 * len), 0.95 * rf);
      b.cylinder(out - dir * (0.25 * len), out, 0.95 * rf);
      b.sphere(m, 0.5 * len);
      handwheel(m + up * (0.4 * len), up, 1.4 * s.od_m + 0.2);
      break;
    case Part::globe_y: {
      b.cylinder(a, a + dir * (0.45 * len), 0.9 * rf);
      b.cylinder(a + dir * (0.45 * len), out, 0.9 * rf);
      const dvec3 bonnet = glm::normalize(up + dir), tilt = glm::normalize(dir - up);
      const dvec3 bonnet_top = m + bonnet * (1.2 * s.od_m + 0.12);
      b.sheared_cylinder(m, bonnet_top, 0.6 * rf, tilt, kQuarterPi, 0.0f);
      handwheel(bonnet_top, bonnet, 0.6 * s.od_m + 0.15);
      break;
    }
    case Part::ball:
      b.cylinder(a, a + dir * (0.2 * len), 0.95 * rf);
      b.cylinder(out - dir * (0.2 * len), out, 0.95 * rf);
      b.sphere(m, 0.42 * len + 0.3 * r);
      b.box(m + up * (0.42 * len + 0.3 * r + 0.04), dir, up,
            dvec3(0.25 + 2.5 * s.od_m, 0.03, 0.02));
      break;
    case Part::ball_sw:
      // Small-bore socket-weld ball valve: the forged body, drawn as its ball.
      b.sphere(m, 0.5 * len);
      break;
    case Part::ball_welded:
      // Butt-welding ends necking down into the ball body.
      b.snout(a, a + dir * (0.3 * len), r, 0.8 * rf, dir);
      b.snout(out - dir * (0.3 * len), out, 0.8 * rf, r, dir);
      b.sphere(m, 0.4 * len + 0.3 * r);
      break;
      // Small-bore socket-weld ball valve: the forged body, drawn as its ball.
      b.sphere(m, 0.5 * len);
      break;
    case Part::check: {
      b.snout(a, m, 0.9 * rf, 0.85 * r, dir);
      b.snout(m, out, 0.85 * r, 0.9 * rf, dir);
      const dvec3 cover = glm::normalize(up + dir), tilt = glm::normalize(dir - up);
      b.sheared_cylinder(m, m + cover * (0.7 * s.od_m + 0.08), 0.55 * rf, tilt, kQuarterPi, 0.0f);
      break;
    }
    case Part::butterfly: {
      b.cylinder(a, out, 0.95 * rf);
      const dvec3 gear = m + up * (rf + 0.12);
      b.box(gear, dir, up, dvec3(0.22, 0.22, 0.2));
      const dvec3 across = glm::normalize(glm::cross(up, dir));
      b.cylinder(gear + across * 0.11, gear + across * 0.14, 0.15 + 0.3 * s.od_m);
      break;
    }
    case Part::control: {
      b.cylinder(a, a + dir * (0.2 * len), 0.95 * rf);
      b.cylinder(out - dir * (0.2 * len), out, 0.95 * rf);
      b.sphere(m, 0.35 * len);
      const dvec3 yoke_top = m + up * (0.35 * len + 0.35 + s.od_m);
      b.cylinder(m + up * (0.3 * len), yoke_top, 0.03 + 0.05 * s.od_m);
      const double rd = 0.16 + 0.6 * s.od_m;
      b.snout(yoke_top, yoke_top + up * 0.12, 0.06, rd, up);
      b.snout(yoke_top + up * 0.12, yoke_top + up * 0.24, rd, 0.06, up);
      break;
    }
    case Part::reducer_conc:
    case Part::reducer_ecc:
      b.snout(a, out, r, 0.5 * pipe_size(it.bore_out).od_m, dir);
      break;
    case Part::strainer: {
      b.cylinder(a, out, 0.42 * rf + 0.5 * r);
      // The screen leg slants down and meets the body along a cut through the run's axis.
      const dvec3 leg = glm::normalize(dir - up), tilt = glm::normalize(dir + up);
      const dvec3 leg_end = m + leg * (0.9 * s.od_m + 0.12);
      b.sheared_cylinder(m, leg_end, 0.6 * r + 0.01, tilt, kQuarterPi, 0.0f);
      b.cylinder(leg_end, leg_end + leg * 0.04, 0.6 * r + 0.03);
      break;
    }
    case Part::trap:
      b.sphere(m, 0.5 * len);
      break;
    case Part::orifice: {
      b.cylinder(a, out, rf * 1.02);
      for (double side : {-1.0, 1.0}) {
        const dvec3 tap = a + dir * (side < 0 ? -0.03 : len + 0.03);
        b.cylinder(tap + up * (0.9 * rf), tap + up * (rf + 0.12), 0.012);
      }
      break;
    }
    case Part::spectacle: {
      b.cylinder(a, out, 0.5 * (r + rf));
      const dvec3 other = m + up * (2.2 * rf);
      b.cylinder(other - dir * (0.5 * len), other + dir * (0.5 * len), 0.5 * (r + rf));
      b.box(m + up * (1.1 * rf), dir, up, dvec3(len, 0.3 * rf, 1.2 * rf));
      break;
    }
    default:
      assert(false && "not a straight member");
  }
  return out;
}

Colour colour_of(Part part, Service service) {
  switch (part) {
    case Part::flange_so:
    case Part::flange_wn:
    case Part::gasket:
    case Part::blind:
    case Part::spectacle:
      return kFlangeGrey;
    case Part::gate:
    case Part::globe:
    case Part::globe_y:
    case Part::ball:
    case Part::check:
    case Part::ball_welded:
    case Part::ball_sw:
    case Part::trap:
    case Part::butterfly:
      return kValveRed;
    case Part::control:
    case Part::orifice:
      return kInstrumentYellow;
    default:
      return service_info(service).colour;
  }
}

}  // namespace

const ServiceInfo& service_info(Service service) { return kServices[size_t(service)]; }

const Mix& part_mix(Part part) { return kPartMixes[size_t(part)]; }

bool is_closure(Part part) {
  return part == Part::blind || part == Part::cap || part == Part::plug;
}

double item_length(const Item& it) {
  const PipeSize& s = pipe_size(it.bore_in);
  switch (it.part) {
    case Part::tee:
      return 2.0 * tee_half(it.bore_in);
    case Part::weld:
      return 0.0;
    case Part::flange_so:
    case Part::flange_wn:
      return s.flange_thk_m;
    case Part::gasket:
      return 0.003;
    case Part::blind:
      return 0.8 * s.flange_thk_m;
    case Part::cap:
      return 0.25 * s.od_m;
    case Part::plug:
      return 0.05;
    case Part::gate:
    case Part::check:
      return s.valve_len_m;
    case Part::globe:
      return 1.15 * s.valve_len_m;
    case Part::globe_y:
      return 1.2 * s.valve_len_m;
    case Part::ball:
    case Part::ball_welded:
      return 0.9 * s.valve_len_m;
    case Part::ball_sw:
      return 0.8 * s.valve_len_m;
    case Part::butterfly:
      return std::max(0.05, 0.25 * s.valve_len_m);
    case Part::control:
      return 1.2 * s.valve_len_m;
    case Part::reducer_conc:
    case Part::reducer_ecc:
      return 0.076 + 0.6 * std::max(s.od_m, pipe_size(it.bore_out).od_m);
    case Part::strainer:
      return 1.3 * s.valve_len_m;
    case Part::trap:
      return 1.6 * s.valve_len_m;
    case Part::orifice:
    case Part::spectacle:
      return 0.01;
    default:
      return 0.0;
  }
}

dvec3 advance(const dvec3& from, const Item& it, const dvec3& dir) {
  return from + dir * item_length(it) + item_shift(it, dir);
}

dvec3 item_shift(const Item& it, const dvec3& dir) {
  if (it.part != Part::reducer_ecc) return dvec3(0.0);
  // Flat on top: the outlet axis moves up (or across, on a vertical run) by the radius change.
  const double dr = 0.5 * (pipe_size(it.bore_in).od_m - pipe_size(it.bore_out).od_m);
  return stem_direction(dir) * dr;
}

// ---------------------------------------------------------------------------------------------

Run::Run(LineContext& line, int branch_number, const Port& head)
    : line_(line),
      name_(line.name + "-B" + std::to_string(branch_number)),
      pos_(head.position),
      dir_(head.direction),
      bore_(head.bore) {}

ObjectBuilder Run::begin(ObjectClass object_class) const {
  return ObjectBuilder(line_.unit.origin_m, pos_, object_class);
}

std::string Run::member_name(const char* type) {
  for (auto& [t, n] : counters_) {
    if (t == type) return name_ + "/" + type + "-" + std::to_string(++n);
  }
  counters_.push_back({type, 1});
  return name_ + "/" + type + "-1";
}

void Run::emit(ObjectBuilder& b, Part part, std::string name, const char* stype) {
  Object& o = b.object();
  o.pipeline_id = line_.id;
  o.colour = colour_of(part, line_.service);
  const PartInfo& info = kParts[size_t(part)];
  b.attribute("Type", info.type);
  b.attribute("Stype", stype ? stype : info.stype);
  b.attribute("Bore", bore_text(bore_));
  b.attribute("Spec", line_.spec);
  b.attribute("Rating", line_.rating);
  if (info.material[0] != '\0') b.attribute("Material", info.material);
  b.attribute("Pipeline", line_.name);
  b.attribute("Branch", name_);
  assert(part == Part::weld || mix_of(o).n == part_mix(part).n);
  members_.push_back(line_.unit.id(name));
  line_.unit.emit(b, std::move(name));
}

void Run::straight(const Item& it) {
  if (it.part == Part::weld) {
    weld();
    return;
  }
  const bool closure = is_closure(it.part);
  ObjectBuilder b = begin(ObjectClass::component);
  const dvec3 a = pos_;
  const dvec3 out = shape_item(b, it, a, dir_);
  const double od_in = pipe_size(it.bore_in).od_m, od_out = pipe_size(it.bore_out).od_m;
  b.connection(a, -dir_, od_in);
  if (!closure) b.connection(out, dir_, od_out);
  if (glm::length(out - a) > 0.0) b.centreline(a, out, od_in);
  const PartInfo& info = kParts[size_t(it.part)];
  std::string name = member_name(info.type);
  if (std::string_view(info.type) == "VALV" || std::string_view(info.type) == "INST") {
    const char* prefix = it.part == Part::control ? "FV" : it.part == Part::orifice ? "FE" : "HV";
    b.attribute("Tag", std::string(prefix) + "-" + line_.name.substr(line_.name.find('-') + 1) +
                           "-" + std::to_string(++line_.tag_seq));
  }
  if (it.bore_out != it.bore_in) b.attribute("Outlet bore", bore_text(it.bore_out));
  emit(b, it.part, std::move(name));
  pos_ = out;
  bore_ = it.bore_out;
}

void Run::pipe_to(const dvec3& end) {
  const double length = glm::dot(end - pos_, dir_);
  assert(length > 0.0);
  const double od = pipe_size(bore_).od_m;
  ObjectBuilder b = begin(ObjectClass::pipe);
  const dvec3 a = pos_, e = pos_ + dir_ * length;
  b.cylinder(a, e, 0.5 * od);
  b.connection(a, -dir_, od);
  b.connection(e, dir_, od);
  b.centreline(a, e, od);
  b.attribute("Length", fixed(length, 3) + " m");
  b.attribute("Schedule", pipe_size(bore_).dn >= 300 ? "STD" : "40");
  pipes_.push_back({a, e, bore_});
  emit(b, Part::pipe, member_name("TUBE"));
  pos_ = e;
}

void Run::elbow(const dvec3& corner, const dvec3& d_out) {
  const PipeSize& s = pipe_size(bore_);
  const double bend_r = s.elbow_r_m * line_.bend_factor;
  const dvec3 p1 = pos_, p2 = corner + d_out * bend_r;
  ObjectBuilder b = begin(ObjectClass::component);
  b.elbow(corner, dir_, d_out, bend_r, 0.5 * s.od_m);
  b.connection(p1, -dir_, s.od_m);
  b.connection(p2, d_out, s.od_m);
  b.centreline(p1, corner, s.od_m);
  b.centreline(corner, p2, s.od_m);
  b.attribute("Angle", "90 deg");
  elbows_.push_back({corner, dir_, d_out, bore_});
  const char* stype = line_.bend_factor > 3.0   ? "5D BEND"
                      : line_.bend_factor > 1.5 ? "3D BEND"
                                                : nullptr;
  emit(b, Part::elbow, member_name("ELBO"), stype);
  pos_ = p2;
  dir_ = d_out;
}

Port Run::tee(const dvec3& branch_dir, int branch_bore) {
  const PipeSize& s = pipe_size(bore_);
  const double c = tee_half(bore_);
  const dvec3 a = pos_, e = pos_ + dir_ * (2.0 * c), m = pos_ + dir_ * c;
  const dvec3 port = m + branch_dir * c;
  const double ob = pipe_size(branch_bore).od_m;
  ObjectBuilder b = begin(ObjectClass::component);
  b.cylinder(a, e, 0.5 * s.od_m);
  b.cylinder(m, port, 0.5 * ob);
  b.connection(a, -dir_, s.od_m);
  b.connection(e, dir_, s.od_m);
  b.connection(port, branch_dir, ob);
  b.centreline(a, e, s.od_m);
  b.centreline(m, port, ob);
  if (branch_bore != bore_) {
    b.attribute("Branch bore", bore_text(branch_bore));
  }
  emit(b, Part::tee, member_name("TEE"), branch_bore != bore_ ? "REDUCING" : nullptr);
  pos_ = e;
  return Port{port, branch_dir, branch_bore};
}

Port Run::olet(const dvec3& branch_dir, int branch_bore) {
  const PipeSize& s = pipe_size(bore_);
  const double ob = pipe_size(branch_bore).od_m;
  const dvec3 m = pos_;
  const dvec3 port = m + branch_dir * (0.5 * s.od_m + 0.06 + 1.2 * ob);
  ObjectBuilder b = begin(ObjectClass::component);
  // The body's foot is cut on a slant where it saddles the run.
  b.sheared_cylinder(m + branch_dir * (0.4 * s.od_m), port, 0.5 * ob + 0.012, dir_, 0.2f, 0.0f);
  b.connection(m, -dir_, s.od_m);
  b.connection(m, dir_, s.od_m);
  b.connection(port, branch_dir, ob);
  b.centreline(m, port, ob);
  b.attribute("Branch bore", bore_text(branch_bore));
  emit(b, Part::olet, member_name("OLET"));
  return Port{port, branch_dir, branch_bore};
}

void Run::weld() {
  const double od = pipe_size(bore_).od_m;
  ObjectBuilder b = begin(ObjectClass::component);
  b.connection(pos_, -dir_, od);
  b.connection(pos_, dir_, od);
  emit(b, Part::weld, member_name("WELD"));
}

void Run::finish() { line_.branches.push_back(Branch{name_, std::move(members_)}); }

// ---------------------------------------------------------------------------------------------

void build_support(LineContext& line, Part part, const dvec3& at, const dvec3& dir, int bore,
                   double ground_z, const dvec3& toward_steel) {
  const PipeSize& s = pipe_size(bore);
  const double r = 0.5 * s.od_m;
  ObjectBuilder b(line.unit.origin_m, at, ObjectClass::component);
  const dvec3 across =
      std::abs(dir.z) < 0.9 ? glm::normalize(glm::cross(kUp, dir)) : dvec3(1, 0, 0);
  const dvec3 along = std::abs(dir.z) < 0.9 ? dir : dvec3(0, 1, 0);
  dvec3 toward = -kUp;
  switch (part) {
    case Part::shoe:
    case Part::shoe_gusseted:
    case Part::guide: {
      // A T-section shoe welded under the pipe, sliding on the beam.
      const double bottom = at.z - r;
      const double h = std::max(0.02, bottom - ground_z - 0.015);
      b.box(dvec3(at.x, at.y, ground_z + 0.015 + 0.5 * h), along, kUp, dvec3(0.3, 0.02, h));
      b.box(dvec3(at.x, at.y, ground_z + 0.0075), along, kUp, dvec3(0.3, 0.2, 0.015));
      if (part == Part::shoe_gusseted) {
        for (double side : {-1.0, 1.0}) {
          b.wedge(dvec3(at.x, at.y, ground_z + 0.015) + across * (side * 0.01), across * side, kUp,
                  0.08, 0.01, 0.8 * h);
        }
      }
      if (part == Part::guide) {
        for (double side : {-1.0, 1.0}) {
          b.box(dvec3(at.x, at.y, ground_z + 0.04) + across * (side * 0.14), along, kUp,
                dvec3(0.1, 0.02, 0.08));
        }
      }
      break;
    }
    case Part::bracket:
    case Part::bracket_braced: {
      // A cantilever arm from the steel (or vessel wall) beside the pipe, with 45 degree knee
      // braces (tubes) cut square to the wall below and to the arm above.
      toward = toward_steel;
      const dvec3 h = toward_steel;
      const double arm_z = std::abs(dir.z) > 0.5 ? at.z : at.z - r - 0.05;
      const dvec3 base(at.x, at.y, arm_z);
      b.box(base + h * (0.5 * (r + 0.6) - 0.05), h, kUp, dvec3(r + 0.7, 0.1, 0.1));
      const dvec3 side = glm::normalize(glm::cross(kUp, h));
      for (int i = 0; i < (part == Part::bracket ? 1 : 2); ++i) {
        const dvec3 off = part == Part::bracket ? dvec3(0.0) : side * (i == 0 ? -0.04 : 0.04);
        const dvec3 high = base + h * (r + 0.15) - kUp * 0.05 + off;
        const dvec3 low = base + h * (r + 0.6) - kUp * 0.5 + off;
        b.sheared_cylinder(low, high, 0.025, glm::normalize(-h - kUp), -kQuarterPi, kQuarterPi);
      }
      break;
    }
    case Part::strut: {
      // A tube strut from the pipe's side down to the steel beside it at 45 degrees, both ends
      // cut square to those vertical faces.
      toward = toward_steel;
      const dvec3 h = toward_steel;
      const dvec3 top = at + h * r;
      const dvec3 bottom = top + h * 0.5 - kUp * 0.5;
      b.sheared_cylinder(top, bottom, 0.025, glm::normalize(h + kUp), -kQuarterPi, -kQuarterPi);
      break;
    }
    case Part::trunnion: {
      // A pipe stub welded square under an elbow's outer curve, resting on a base plate on the
      // steel below; its top is cut at 45 degrees along the bend.
      const double rs = std::min(0.15, std::max(0.03, 0.7 * r));
      const dvec3 foot(at.x, at.y, ground_z + 0.02);
      b.sheared_cylinder(foot, at, rs, along, 0.0f, -kQuarterPi);
      b.box(dvec3(at.x, at.y, ground_z + 0.01), along, kUp,
            dvec3(2.4 * rs + 0.1, 2.4 * rs + 0.1, 0.02));
      break;
    }
    case Part::clamp:
      // A split ring clamped round the pipe, bearing on the steel it passes.
      toward = toward_steel;
      b.rect_torus(at, along, across, r + 0.002, r + 0.05, 0.06, kFullTurn);
      break;
    case Part::hanger: {
      toward = kUp;
      b.rect_torus(at, along, across, r + 0.002, r + 0.012, 0.05, kFullTurn);
      b.cylinder(at + kUp * (r + 0.012), dvec3(at.x, at.y, ground_z - 0.02), 0.01 + 0.02 * r);
      b.box(dvec3(at.x, at.y, ground_z - 0.01), along, kUp, dvec3(0.2, 0.2, 0.02));
      break;
    }
    case Part::stanchion: {
      const double bottom = at.z - r;
      const double rs = std::min(0.08, std::max(0.03, 0.6 * r));
      b.cylinder(dvec3(at.x, at.y, ground_z + 0.02), dvec3(at.x, at.y, bottom - 0.02), rs);
      b.box(dvec3(at.x, at.y, ground_z + 0.01), along, kUp, dvec3(0.35, 0.35, 0.02));
      b.box(dvec3(at.x, at.y, bottom - 0.01), along, kUp,
            dvec3(0.25, std::max(0.1, 1.4 * r), 0.02));
      break;
    }
    case Part::dummy_leg:
    case Part::dummy_leg_bare:
    case Part::dummy_leg_gusseted: {
      // A pipe stub under an elbow, its top cut at 45 degrees along the bend (tilted toward
      // `dir`, the elbow's horizontal leg direction), standing on a base plate.
      const double rs = std::min(0.15, std::max(0.03, 0.7 * r));
      const dvec3 foot(at.x, at.y, ground_z + 0.02);
      b.sheared_cylinder(foot, at, rs, along, 0.0f, -kQuarterPi);
      if (part != Part::dummy_leg_bare) {
        b.box(dvec3(at.x, at.y, ground_z + 0.01), along, kUp,
              dvec3(2.6 * rs + 0.1, 2.6 * rs + 0.1, 0.02));
      }
      if (part == Part::dummy_leg_gusseted) {
        for (double side : {-1.0, 1.0}) {
          b.wedge(foot + across * (side * rs), across * side, kUp, 0.08, 0.012, 0.15);
        }
      }
      break;
    }
    default:
      assert(false && "not a support");
  }
  b.connection(at, toward, s.od_m);
  Object& o = b.object();
  o.pipeline_id = line.id;
  o.colour = kSupportGrey;
  const PartInfo& info = kParts[size_t(part)];
  b.attribute("Type", info.type);
  b.attribute("Stype", info.stype);
  b.attribute("Bore", bore_text(bore));
  b.attribute("Material", info.material);
  b.attribute("Pipeline", line.name);
  assert(mix_of(o).n == part_mix(part).n);
  line.unit.emit(b, line.name + "/SUPP-" + std::to_string(++line.support_count));
}

}  // namespace plantview::gen
