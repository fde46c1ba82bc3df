// Helpers every hitex shader shares, prepended to each before it is compiled
// (src/gpu: TEXTURED_WGSL, BTF_WGSL, NURBS source, TERRAIN_WGSL).

// Linear light to the sRGB transfer curve, [0, 1] in and out (the CPU's
// hitex_core::texture::linear_to_srgb_u8 rounds the same curve to 8 bits).
fn linear_to_srgb(l: f32) -> f32 {
    let c = clamp(l, 0.0, 1.0);
    if c <= 0.0031308 {
        return c * 12.92;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}


// Linear RGB to an opaque sRGB-encoded colour target value.
fn encode(c: vec3<f32>) -> vec4<f32> {
    return vec4<f32>(linear_to_srgb(c.x), linear_to_srgb(c.y), linear_to_srgb(c.z), 1.0);
}
