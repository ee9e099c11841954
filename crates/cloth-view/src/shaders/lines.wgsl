// Unlit coloured lines: wireframe, springs by class, pin markers. Pulled slightly towards the
// camera so they draw over the surface they lie on.

struct Globals {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    light_dir: vec4<f32>,
    light_color: vec4<f32>,
    cloth_front: vec4<f32>,
    cloth_back: vec4<f32>,
    background: vec4<f32>,
    shadow_sphere: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec3<f32>,
};

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) color: vec3<f32>) -> VertexOut {
    var out: VertexOut;
    var clip = globals.view_proj * vec4<f32>(position, 1.0);
    clip.z = clip.z - 0.0004 * clip.w;
    out.clip = clip;
    out.color = color;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.color, 1.0);
}
