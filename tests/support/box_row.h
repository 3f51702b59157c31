// The service tests' plant: six 2 m boxes along x (at 0, 3, ..., 15 m), each an equipment item
// with a colour of its own and the attributes Type and Index, so that frames are quick on a CPU.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "plantview/model.h"

namespace plantview::test {

inline std::vector<Object> box_row_objects() {
  std::vector<Object> objects;
  for (int i = 0; i < 6; ++i) {
    Object o;
    o.name = "/BOX-" + std::to_string(i);
    o.source = "test";
    o.id = object_id(o.source, o.name);
    o.object_class = ObjectClass::equipment;
    o.origin_m = {i * 3.0, 0, 0};
    o.colour = {uint8_t(40 * i), 120, 200, 255};
    o.primitives.push_back(Primitive{Placement{}, Box{2, 2, 2}});
    o.attributes = {{"Type", "EQUI"}, {"Index", std::to_string(i)}};
    objects.push_back(std::move(o));
  }
  return objects;
}

}  // namespace plantview::test
