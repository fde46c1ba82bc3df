// The flight fragment program. Twin of `src/cpu/terrain.rs`: the same
// uniforms and page table, the same steps in the same order.

struct Fly {
    eye: vec4<f32>,    // xyz eye (finest texels), w tan of half the horizontal FOV
    fwd: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    sizes: vec4<u32>,  // width, height, levels, maps per window side
}

struct Pages {
    origins: array<vec4<i32>, 32>,  // per level: first map column, row
    slots: array<vec2<i32>>,        // per level and slot: (layer, level of the serving map); layer < 0: no data
}

@group(0) @binding(0) var<uniform> fly: Fly;
@group(0) @binding(1) var<storage, read> pages: Pages;
@group(0) @binding(2) var maps: texture_2d_array<f32>;

const MAP: i32 = 256;
const GROUND: vec3<f32> = vec3<f32>(0.05, 0.06, 0.05);

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // one triangle covering the screen
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    return vec4<f32>(x, y, 0.0, 1.0);
}

struct Hit {
    ok: bool,
    p: vec2<f32>,
}

// the ground point through pixel position (px, py); not ok at and above the horizon
fn ground(px: f32, py: f32) -> Hit {
    let w = f32(fly.sizes.x);
    let h = f32(fly.sizes.y);
    let tan_h = fly.eye.w;
    let sx = (2.0 * px / w - 1.0) * tan_h;
    let sy = (1.0 - 2.0 * py / h) * tan_h * h / w;
    let d = fly.fwd.xyz + fly.right.xyz * sx + fly.up.xyz * sy;
    if (d.z >= -1e-6) {
        return Hit(false, vec2<f32>(0.0));
    }
    let t = -fly.eye.z / d.z;
    return Hit(true, fly.eye.xy + d.xy * t);
}

// linear RGBA of texel (tx, ty) of level z through the page table
fn texel(z_in: u32, tx_in: i32, ty_in: i32) -> vec4<f32> {
    let per = i32(fly.sizes.w);
    var z = z_in;
    var tx = tx_in;
    var ty = ty_in;
    loop {
        let o = pages.origins[z].xy;
        let mx = (tx >> 8u) - o.x;
        let my = (ty >> 8u) - o.y;
        if (mx >= 0 && my >= 0 && mx < per && my < per) {
            let slot = pages.slots[i32(z) * per * per + my * per + mx];
            if (slot.x < 0) {
                return vec4<f32>(0.0);
            }
            // a coarser resident map stands in: its texel containing this one
            let k = z - u32(slot.y);
            let lx = (tx >> k) & (MAP - 1);
            let ly = (ty >> k) & (MAP - 1);
            return textureLoad(maps, vec2<i32>(lx, ly), slot.x, 0);
        }
        // outside the active area: the next coarser level covers it
        if (z == 0u) {
            return vec4<f32>(0.0);
        }
        z = z - 1u;
        tx = tx >> 1u;
        ty = ty >> 1u;
    }
    return vec4<f32>(0.0);
}

fn bilinear(z: u32, p: vec2<f32>) -> vec4<f32> {
    let s = f32(1u << (fly.sizes.z - 1u - z));
    let q = p / s - vec2<f32>(0.5);
    let q0 = floor(q);
    let f = q - q0;
    let ix = i32(q0.x);
    let iy = i32(q0.y);
    let c0 = texel(z, ix, iy);
    let c1 = texel(z, ix + 1, iy);
    let c2 = texel(z, ix, iy + 1);
    let c3 = texel(z, ix + 1, iy + 1);
    let top = c0 + (c1 - c0) * f.x;
    let bot = c2 + (c3 - c2) * f.x;
    return top + (bot - top) * f.y;
}

fn linear_to_srgb(l: f32) -> f32 {
    let c = clamp(l, 0.0, 1.0);
    if c <= 0.0031308 {
        return c * 12.92;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

@fragment
fn fs_main(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let x = frag.x;
    let y = frag.y;
    let a = ground(x, y);
    let b = ground(x + 1.0, y);
    let c = ground(x, y + 1.0);
    var rgb: vec3<f32>;
    if (!(a.ok && b.ok && c.ok)) {
        let s = 1.0 - y / f32(fly.sizes.y);
        rgb = vec3<f32>(0.55 + 0.2 * s, 0.68 + 0.15 * s, 0.86);
    } else {
        // eq. (2): the largest partial of the screen-to-map mapping
        let d1 = abs(b.p - a.p);
        let d2 = abs(c.p - a.p);
        let foot = max(max(d1.x, d1.y), max(d2.x, d2.y));
        let levels = fly.sizes.z;
        let zf = clamp(f32(levels - 1u) - log2(max(foot, 1e-9)), 0.0, f32(levels - 1u));
        let z0 = u32(floor(zf));
        let z1 = min(z0 + 1u, levels - 1u);
        let t = zf - f32(z0);
        let s0 = bilinear(z0, a.p);
        var s1 = s0;
        if (z1 != z0 && t > 0.0) {
            s1 = bilinear(z1, a.p);
        }
        let s = s0 + (s1 - s0) * t;
        rgb = s.rgb + GROUND * (1.0 - s.a);
    }
    return vec4<f32>(linear_to_srgb(rgb.x), linear_to_srgb(rgb.y), linear_to_srgb(rgb.z), 1.0);
}
