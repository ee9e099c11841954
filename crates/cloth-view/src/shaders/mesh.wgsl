// Lit surfaces: the cloth (double-sided, a fabric pattern from its UVs), the collider spheres
// and the ground, all Blinn-Phong with one directional light.

struct Globals {
    view_proj: mat4x4<f32>,
    // xyz: eye position (m)
    eye: vec4<f32>,
    // xyz: unit vector towards the light
    light_dir: vec4<f32>,
    // rgb: light colour; w: ambient strength
    light_color: vec4<f32>,
    // rgb: front of the cloth; w: pattern squares across the cloth
    cloth_front: vec4<f32>,
    // rgb: back of the cloth; w: 1 = pattern on, 0 = plain
    cloth_back: vec4<f32>,
    // rgb: the background (fog) colour, linear; w: fog start distance (m)
    background: vec4<f32>,
    // xyz: centre of the sphere that shadows the ground; w: its radius (0 = none)
    shadow_sphere: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) material: u32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) material: u32,
};

const CLOTH: u32 = 0u;
const SPHERE: u32 = 1u;
const GROUND: u32 = 2u;

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.uv = v.uv;
    out.material = v.material;
    return out;
}

fn checker(p: vec2<f32>) -> f32 {
    let c = floor(p.x) + floor(p.y);
    return c - 2.0 * floor(c * 0.5);
}

// A woven look: a checker of squares with fine threads along both directions.
fn fabric(uv: vec2<f32>) -> f32 {
    let squares = globals.cloth_front.w;
    let p = uv * squares;
    let check = mix(0.72, 1.0, checker(p));
    let threads = 0.94 + 0.03 * sin(p.x * 6.2831853 * 6.0) + 0.03 * sin(p.y * 6.2831853 * 6.0);
    return mix(1.0, check * threads, globals.cloth_back.w);
}

// 0 in the sphere's shadow, 1 in the light.
fn sphere_shadow(p: vec3<f32>) -> f32 {
    let r = globals.shadow_sphere.w;
    if (r <= 0.0) {
        return 1.0;
    }
    let l = normalize(globals.light_dir.xyz);
    let oc = p - globals.shadow_sphere.xyz;
    let b = dot(oc, l);
    let d2 = dot(oc, oc) - b * b;
    if (b > 0.0) {
        return 1.0;
    }
    // soft edge: distance of the shadow ray from the centre against the radius
    return smoothstep(r * 0.85, r * 1.1, sqrt(max(d2, 0.0)));
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    var base: vec3<f32>;
    var shininess = 32.0;
    var spec_strength = 0.2;
    var shadow = 1.0;
    if (in.material == CLOTH) {
        if (front) {
            base = globals.cloth_front.rgb;
        } else {
            // the back face: its own colour and the flipped normal
            base = globals.cloth_back.rgb;
            n = -n;
        }
        base = base * fabric(in.uv);
        shininess = 24.0;
        spec_strength = 0.12;
    } else if (in.material == SPHERE) {
        base = vec3<f32>(0.62, 0.64, 0.68);
        shininess = 60.0;
        spec_strength = 0.45;
    } else {
        base = mix(vec3<f32>(0.16, 0.17, 0.19), vec3<f32>(0.21, 0.22, 0.24), checker(in.uv * 4.0));
        shininess = 16.0;
        spec_strength = 0.05;
        shadow = sphere_shadow(in.world);
        if (!front) {
            n = -n;
        }
    }
    let l = normalize(globals.light_dir.xyz);
    let v = normalize(globals.eye.xyz - in.world);
    let h = normalize(l + v);
    let ambient = globals.light_color.w * base;
    let diffuse = max(dot(n, l), 0.0) * base * globals.light_color.rgb;
    let specular = pow(max(dot(n, h), 0.0), shininess) * spec_strength * globals.light_color.rgb;
    // a faint fill light from below-behind so shaded sides keep their shape
    let fill = 0.12 * max(dot(n, normalize(vec3<f32>(-0.4, 0.3, -0.8))), 0.0) * base;
    var color = ambient + fill + shadow * (diffuse + specular);
    // fog towards the background colour with distance (hides the ground's edge)
    let dist = length(globals.eye.xyz - in.world);
    let fog = smoothstep(globals.background.w, globals.background.w * 3.0, dist);
    color = mix(color, globals.background.rgb, fog);
    return vec4<f32>(color, 1.0);
}
