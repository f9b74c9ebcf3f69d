// Shading of `clustered` (Persson 2013): tiled_lighting.frag with the cell chosen by
// (tile, exponential depth slice of the pixel's view depth).
#define CLUSTERED 1
#include "tiled_lighting.frag"
