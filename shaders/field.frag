// The light field's cell, bilinearly filtered between cell centres (the texture's filter).

in vec2 v_uv;
out vec4 o_colour;

uniform sampler2D u_field;

void main() { o_colour = vec4(texture(u_field, v_uv).rgb, 1.0); }
