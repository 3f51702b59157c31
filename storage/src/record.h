// Internal: the binary layout of object and attribute records, before compression.
//
// Object record (little-endian, no padding):
//   u8 layout version (4) | u8 class | u8 r,g,b,a | u64 id | f64 origin[3]
//   | str name | str source | u64 pipeline_id
//   | u32 primitive count | primitives... | u32 connections | (f32 pos[3], dir[3], diameter)...
//   | u32 segments | (f32 start[3], end[3], diameter)... | u32 branches | (str name, u32 n, u64 ids[n])...
// str = u32 length + bytes. A primitive is: u8 kind | u8 placement code | [f32 scale]
//   | f32 translation[3] | [f32 linear[9] when code is 0xff] | the kind's fields as f32 (u32 for
//   a prism's sides); a facet group: u32 polygons, u32 contours, u32 vertices, u32 triangles,
//   polygon_ends, contour_ends, vertices (f32 position[3], normal[3]), triangles (u32).
// Placement code: bits 0-5: 1 + permutation * 8 + sign bits for an axis-aligned linear part
//   (columns are +-scale times unit axes), with bit 7 set when a scale other than 1 follows;
//   0xff: a general linear part of 9 floats. Lossless either way, bit for bit, with one
//   exception: the zero entries of an axis-aligned linear part come back as +0.0 whatever their
//   sign (it has no geometric meaning; preset a has -0.0 there in a third of such placements,
//   and keeping it would cost the compact code its size).
// Attribute record: u32 count | (str key, str value)...
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "plantview/model.h"

namespace plantview::detail {

// The id is part of the record (format 3): object() and for_each_object() need no table of the
// id of every slot.
void encode_object(const Object& object, std::vector<uint8_t>& out);
// Decodes an object record (attributes left empty); false with a message on a malformed
// record.
bool decode_object(const uint8_t* data, size_t size, Object& out, std::string& error);
// A record's id and pipeline id alone, from its first bytes (decode_object's checks on them);
// false with a message on a record too short to hold them or of another layout.
bool decode_object_key(const uint8_t* data, size_t size, uint64_t& id, uint64_t& pipeline_id,
                       std::string& error);

void encode_attributes(const std::vector<Attribute>& attributes, std::vector<uint8_t>& out);
bool decode_attributes(const uint8_t* data, size_t size, std::vector<Attribute>& out,
                       std::string& error);

}  // namespace plantview::detail
