// A top-layer header; including the layer below is allowed.
#include "low/low.h"
