#version 450
// Probe view: cell outlines in a constant colour (linear, before tone mapping).
layout(location = 0) out vec4 out_color;
void main() { out_color = vec4(0.9, 0.75, 0.2, 1.0); }
