// Fading by age: drawn with blending (zero, constant colour), which multiplies the accumulated
// path light by the blend constant; the shader's own output is ignored.

out vec4 o_colour;

void main() { o_colour = vec4(0.0); }
