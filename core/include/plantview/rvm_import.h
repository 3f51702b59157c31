// plantview/rvm_import.h: turning a parsed RVM file and its attribute file into plant objects.
//
// Objects (which groups become what)
//   - The PDMS `Type` attribute of a group's attribute block (matched by group name) decides:
//       SITE, ZONE, WORL: containers; their children are looked at one by one.
//       EQUI: one equipment object with every primitive of its subtree (sub-equipment, nozzles).
//       PIPE: a pipeline object (no primitives) whose branches are its BRAN children; in each
//         branch, the child groups in file order are its members: TUBE (and implied tube) groups
//         become pipes, every other child (ELBO, BEND, TEE, OLET, FLAN, GASK, VALV, REDU, CAP,
//         INST, PCOM, ...) a component.
//       STRU, FRMW, SBFR, SUBS, SCTN, PANE, GENSEC and the like: structure. Each such group with
//         primitives of its own (directly or through primitive-element children) is one object.
//       Primitive elements (BOX, CYLI, CONE, SNOU, DISH, PYRA, TORU, RTOR, SLCY, EXTR, REVO, POHE,
//         POLY, TEXT, DRAW, NBOX, NCYL...) are not objects: their primitives belong to the
//         nearest enclosing object.
//       Any other type, or a group without an attribute block: an object of its enclosing class
//         (structure below a structure, otherwise other) if it holds primitives of its own.
//   - Without an attribute file, every group holding primitives is an object of class other.
//   - Attributes are kept with their object (the block's key/value pairs, bytes as given),
//     followed by "Site" and "Zone": the names of the SITE and ZONE groups that enclose it (the
//     hierarchy containers leave behind; areas of review views), where there are such groups and
//     the block has no key of that name.
//   - Names repeat in some files; a repeated name gets " #2", " #3"... so that ids stay unique.
//
// Piping derivation: a pipe's centreline is its longest cylinder's (or snout's) axis, with a
// connection point at each end pointing outward, diameter twice the radius. A component's
// connection points are the ends of its elbow sweep (a torus) or else of its longest cylinder or
// snout axis; its centreline joins them (through the bend's corner for an elbow). Members get
// their pipeline's id.
//
// Frames: each object's origin is its first primitive's translation (double precision); its
// primitives, connection points and centreline are stored relative to it.
// Colours: transparency becomes alpha; the colour comes from the class (RVM material indices
// have no standard table).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "plantview/model.h"
#include "plantview/rvm.h"

namespace plantview {

struct RvmImportSummary {
  uint64_t groups = 0, primitives = 0, objects = 0;
  uint64_t groups_with_attributes = 0;  // groups whose name matched an attribute block
  std::vector<std::string> warnings;    // the parser's and this conversion's
};

// Converts `file` (with `attributes`, or null) to objects whose source is `source`.
std::vector<Object> rvm_to_objects(const RvmFile& file, const AttributeFile* attributes,
                                   std::string_view source, RvmImportSummary& summary);

}  // namespace plantview
