#version 460
// Test-only shader for the validation negative test: it stores one element
// past the end of its buffer, which GPU-assisted validation must report.
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Out { uint data[]; };
layout(push_constant) uniform Push { uint len; } pc;
void main() {
    data[pc.len] = 0xBADu; // deliberately out of bounds
}
