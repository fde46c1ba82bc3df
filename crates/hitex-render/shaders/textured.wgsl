// The textured-mesh fragment program. Twin of src/cpu/textured.rs (and of the
// sampler in hitex-core/src/texture/sampler.rs): same inputs in binding order,
// same steps in the same order; change both together.

struct Light {
    vector: vec4<f32>,   // xyz direction of travel (w = 0) or position (w = 1)
    radiance: vec4<f32>, // rgb × intensity
};

struct Frame {
    view_proj: mat4x4<f32>,
    camera: vec4<f32>,
    ambient: vec4<f32>,
    background: vec4<f32>,
    params: vec4<u32>, // x: mode, y: light count
    lights: array<Light, 8>,
};

struct Material {
    base_color: vec4<f32>,
    uv_scale: vec2<f32>,
    specular: f32,
    shininess: f32,
    has_texture: u32,
    filter_mode: u32, // FILTER_*
    wrap: u32,       // WRAP_*
    level_rule: u32, // LEVEL_RULE_* (max-partial: paper eq. 2)
    lod_bias: f32,
    level_count: u32,
    size: vec2<u32>,
    atlas_size: vec2<u32>,
    one_sided: u32,  // 1: the normal as authored, also seen from behind
    _pad: u32,
    origins: array<vec4<u32>, 8>, // level 2k at .xy, level 2k+1 at .zw
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<uniform> material: Material;
// Every MIP level of the texture in one atlas (prepare.rs, AtlasLayout),
// read at level of detail 0: see level_texel().
@group(1) @binding(1) var tex: texture_2d<f32>;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) w: f32,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var o: VsOut;
    o.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    o.world = v.position;
    o.normal = v.normal;
    o.uv = v.uv;
    o.w = o.clip.w;
    return o;
}

// ---- sampler (hitex-core texture::sampler) ----

const NO_LEVEL: f32 = -1.0e30; // stands for −∞ (magnification)

fn rem_euclid(a: i32, n: i32) -> i32 {
    let r = a % n;
    return select(r, r + n, r < 0);
}

fn wrap_index(i: i32, n: i32, wrap: u32) -> i32 {
    if wrap == WRAP_CLAMP {
        return clamp(i, 0, n - 1);
    }
    if wrap == WRAP_MIRROR {
        let m = rem_euclid(i, 2 * n);
        return select(m, 2 * n - 1 - m, m >= n);
    }
    return rem_euclid(i, n);
}

fn reduce(t: f32, wrap: u32) -> f32 {
    if wrap == WRAP_REPEAT {
        return t - floor(t);
    }
    if wrap == WRAP_MIRROR {
        return t - 2.0 * floor(t * 0.5);
    }
    return clamp(t, -1.0, 2.0);
}

// jac = (du/dx, dv/dx, du/dy, dv/dy) in uv per pixel
fn level_of_detail(rule: u32, jac: vec4<f32>, size: vec2<u32>) -> f32 {
    let s = vec2<f32>(size);
    let ux = jac.x * s.x;
    let vx = jac.y * s.y;
    let uy = jac.z * s.x;
    let vy = jac.w * s.y;
    // level of detail
    var rho: f32;
    if rule == LEVEL_RULE_VULKAN_RHO {
        rho = max(sqrt(ux * ux + vx * vx), sqrt(uy * uy + vy * vy));
    } else {
        rho = max(max(abs(ux), abs(vx)), max(abs(uy), abs(vy)));
    }
    if rho > 0.0 && rho < 3.0e38 {
        return log2(rho);
    }
    return NO_LEVEL;
}

// Size of a MIP level from the uniform (the pyramid rule max(1, n >> l)).
fn level_size(level: i32) -> vec2<i32> {
    return max(vec2<i32>(material.size) >> vec2<u32>(u32(level)), vec2<i32>(1));
}

// Texel (x, y) of a MIP level, in range by construction. The levels live side
// by side in one atlas read at level of detail 0 because drivers disagree on
// per-pixel levels in texel fetches (llvmpipe resolves sizes once per SIMD group).
fn level_texel(level: i32, x: i32, y: i32) -> vec4<f32> {
    let o4 = material.origins[level / 2];
    var o = o4.xy;
    if (level % 2) == 1 {
        o = o4.zw;
    }
    return textureLoad(tex, vec2<i32>(o) + vec2<i32>(x, y), 0);
}

fn nearest(wrap: u32, uv: vec2<f32>) -> vec4<f32> {
    let d = level_size(0);
    let x = wrap_index(i32(floor(uv.x * f32(d.x))), d.x, wrap);
    let y = wrap_index(i32(floor(uv.y * f32(d.y))), d.y, wrap);
    return level_texel(0, x, y);
}

fn bilinear(level: i32, wrap: u32, uv: vec2<f32>) -> vec4<f32> {
    let d = level_size(level);
    let x = uv.x * f32(d.x) - 0.5;
    let y = uv.y * f32(d.y) - 0.5;
    let xf = floor(x);
    let yf = floor(y);
    let alpha = x - xf;
    let beta = y - yf;
    let x0 = i32(xf);
    let y0 = i32(yf);
    let xa = wrap_index(x0, d.x, wrap);
    let xb = wrap_index(x0 + 1, d.x, wrap);
    let ya = wrap_index(y0, d.y, wrap);
    let yb = wrap_index(y0 + 1, d.y, wrap);
    let t00 = level_texel(level, xa, ya);
    let t10 = level_texel(level, xb, ya);
    let t01 = level_texel(level, xa, yb);
    let t11 = level_texel(level, xb, yb);
    let top = t00 + (t10 - t00) * alpha;
    let bottom = t01 + (t11 - t01) * alpha;
    return top + (bottom - top) * beta;
}

fn sample(uv_in: vec2<f32>, jac: vec4<f32>) -> vec4<f32> {
    let uv = vec2<f32>(reduce(uv_in.x, material.wrap), reduce(uv_in.y, material.wrap));
    if material.filter_mode == FILTER_NEAREST {
        return nearest(material.wrap, uv);
    }
    if material.filter_mode == FILTER_BILINEAR {
        return bilinear(0, material.wrap, uv);
    }
    // level selection
    let max_level = f32(material.level_count - 1u);
    let lambda = clamp(level_of_detail(material.level_rule, jac, material.size) + material.lod_bias, 0.0, max_level);
    let l0 = floor(lambda);
    let gamma = lambda - l0;
    // bilinear at L and L+1, linear blend
    let c0 = bilinear(i32(l0), material.wrap, uv);
    if gamma > 0.0 {
        let c1 = bilinear(i32(l0) + 1, material.wrap, uv);
        return c0 + (c1 - c0) * gamma;
    }
    return c0;
}

// ---- output ----


fn level_color(lambda: f32) -> vec3<f32> {
    var colors = array<vec3<f32>, 12>(
        vec3<f32>(0.10, 0.10, 0.60), vec3<f32>(0.10, 0.30, 0.90), vec3<f32>(0.10, 0.60, 0.90),
        vec3<f32>(0.10, 0.80, 0.70), vec3<f32>(0.20, 0.80, 0.30), vec3<f32>(0.55, 0.85, 0.15),
        vec3<f32>(0.90, 0.85, 0.10), vec3<f32>(0.95, 0.60, 0.10), vec3<f32>(0.90, 0.30, 0.10),
        vec3<f32>(0.80, 0.10, 0.20), vec3<f32>(0.70, 0.10, 0.60), vec3<f32>(0.95, 0.95, 0.95));
    if lambda < 0.0 {
        return colors[0] * 0.6;
    }
    let l = min(lambda, 10.999);
    let i = i32(floor(l));
    let f = l - f32(i);
    return colors[i] + (colors[i + 1] - colors[i]) * f;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    // inputs
    let uv = in.uv * material.uv_scale;
    // analytic screen-to-texture Jacobian, eq. (1): uv = U / q with U = uv·q and
    // q = 1/w both linear in screen space, so ∂uv/∂x = (∂U/∂x − uv ∂q/∂x) / q
    let q = 1.0 / in.w;
    let big_u = uv * q;
    let du_x = dpdxFine(big_u);
    let du_y = dpdyFine(big_u);
    let dq_x = dpdxFine(q);
    let dq_y = dpdyFine(q);
    let d_dx = (du_x - uv * dq_x) / q;
    let d_dy = (du_y - uv * dq_y) / q;
    let jac = vec4<f32>(d_dx.x, d_dx.y, d_dy.x, d_dy.y);
    // two-sided normal (one-sided materials keep it as authored)
    let view = normalize(frame.camera.xyz - in.world);
    var n = normalize(in.normal);
    if dot(n, view) < 0.0 && material.one_sided == 0u {
        n = -n;
    }
    let mode = frame.params.x;
    if mode == RENDER_UV {
        return vec4<f32>(uv.x - floor(uv.x), uv.y - floor(uv.y), 0.0, 1.0);
    }
    if mode == RENDER_LEVEL {
        var lambda = NO_LEVEL;
        if material.has_texture == 1u {
            lambda = level_of_detail(material.level_rule, jac, material.size) + material.lod_bias;
        }
        return vec4<f32>(level_color(lambda), 1.0);
    }
    if mode == RENDER_NORMAL {
        return vec4<f32>(n * 0.5 + vec3<f32>(0.5), 1.0);
    }
    // shaded
    var texel = vec4<f32>(1.0);
    if material.has_texture == 1u {
        texel = sample(uv, jac);
    }
    let albedo = material.base_color * texel;
    var diffuse = frame.ambient.xyz;
    var spec = vec3<f32>(0.0);
    let count = min(frame.params.y, 8u);
    for (var i = 0u; i < count; i = i + 1u) {
        let l = frame.lights[i];
        var radiance = l.radiance.xyz;
        var to_light: vec3<f32>;
        if l.vector.w == 0.0 {
            to_light = -l.vector.xyz;
        } else {
            let d = l.vector.xyz - in.world;
            radiance = radiance / max(dot(d, d), 1e-8);
            to_light = normalize(d);
        }
        let ndl = max(dot(n, to_light), 0.0);
        diffuse = diffuse + radiance * ndl;
        if ndl > 0.0 && material.specular > 0.0 {
            let h = normalize(to_light + view);
            spec = spec + radiance * (material.specular * pow(max(dot(n, h), 0.0), material.shininess));
        }
    }
    return encode(albedo.xyz * diffuse + spec);
}
