// Running average of frames: out = mix(history, current, 1/(n+1)).
uniform sampler2D u_current;
uniform sampler2D u_history;
uniform float u_weight;   // 1 / (frames so far + 1)
layout(location = 0) out vec4 o_color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(u_current, px, 0);
    vec4 h = texelFetch(u_history, px, 0);
    o_color = mix(h, c, u_weight);
}
