// TableEntry::pick's fields and the tie-break's step (gl/backend.h: kTieBits, kTieStepInverse;
// program_sources.cpp checks at compile time that these agree with them): the low 32 - kTieBits
// bits index the frame's pick table + 1, the high kTieBits bits are the tie-break t, which draws
// an object's depth t x kTieStep (relative) farther. Put in front of object_table.glsl and
// ground.vert.glsl.
const uint kPickMask = 0x3ffffffu;
const uint kTieShift = 26u;
const float kTieStep = 1.0 / 4194304.0;
