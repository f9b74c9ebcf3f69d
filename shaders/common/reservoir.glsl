// STB reuse (issue 31): a per-pixel reservoir of one light sample, ReSTIR-style.
// y: the light's index in this frame's FoV light buffer (LIM_EMPTY_LIGHT_INDEX: none);
// W: its unbiased contribution weight (the pixel's light estimate is f(y) x W, f the
// shaded, shadowed radiance of light y; 1/sr-free: same units as STB's sample weights);
// M: confidence (candidates' worth; frames x neighbours), p: the target of y when the
// reservoir was stored (the temporal pass compares it with the re-evaluated one).
// Packed as rgba32ui: (y, bits of W, bits of M, bits of p).
#ifndef STB_RESERVOIR_GLSL
#define STB_RESERVOIR_GLSL

struct Reservoir {
    uint y;
    float W;
    float M;
    float p;
};

Reservoir reservoir_empty() {
    Reservoir r;
    r.y = LIM_EMPTY_LIGHT_INDEX; r.W = 0.0; r.M = 0.0; r.p = 0.0;
    return r;
}

uvec4 reservoir_pack(Reservoir r) {
    return uvec4(r.y, floatBitsToUint(r.W), floatBitsToUint(r.M), floatBitsToUint(r.p));
}

Reservoir reservoir_unpack(uvec4 v) {
    Reservoir r;
    r.y = v.x; r.W = uintBitsToFloat(v.y); r.M = uintBitsToFloat(v.z); r.p = uintBitsToFloat(v.w);
    // Anything non-finite or negative (never written so, but history textures start
    // uninitialised) is an empty reservoir.
    if (!(r.W >= 0.0 && r.W < 3.0e38) || !(r.M >= 0.0 && r.M < 3.0e38) || !(r.p >= 0.0 && r.p < 3.0e38)) {
        return reservoir_empty();
    }
    return r;
}

// Streaming weighted selection (A-Chao with one slot): candidate y with resampling
// weight w (>= 0) replaces the current pick with probability w / wsum. py: its target.
struct Stream {
    uint y;
    float py;
    float wsum;
};

Stream stream_empty() {
    Stream s; s.y = LIM_EMPTY_LIGHT_INDEX; s.py = 0.0; s.wsum = 0.0;
    return s;
}

void stream_add(inout Stream s, uint y, float py, float w, float u) {
    if (!(w > 0.0) || isinf(w)) return;
    s.wsum += w;
    if (u * s.wsum < w) {
        s.y = y;
        s.py = py;
    }
}

// The reservoir of a finished stream: W = wsum / (norm x p(y)); norm = M for the
// 1/M combination, 1 where the resampling weights already carry the MIS weights.
Reservoir stream_reservoir(Stream s, float M, float norm) {
    Reservoir r = reservoir_empty();
    r.M = M;
    if (s.wsum > 0.0 && s.py > 0.0 && s.y != LIM_EMPTY_LIGHT_INDEX) {
        float W = s.wsum / (norm * s.py);
        if (W > 0.0 && !isinf(W) && !isnan(W)) {
            r.y = s.y; r.W = W; r.p = s.py;
        }
    }
    return r;
}
#endif
