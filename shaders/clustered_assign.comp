// GPU light assignment of `clustered` (Persson 2013): the tiled culling kernel with
// the cell's depth range taken from its exponential depth slice instead of the
// tile's min/max depth. One workgroup per cluster (x tile, y tile, z slice).
#define CLUSTERED 1
#include "tiled_cull.comp"
