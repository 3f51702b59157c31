// sphere cases: PLACEHOLDER, to be written (see tests/primitives/cylinder_cases.cpp for the pattern).
#include "support/primitive_cases.h"
