// A bottom-layer header that reaches up: the checker must refuse it when
// aerotri::low does not link aerotri::high.
#include "high/high.h"
