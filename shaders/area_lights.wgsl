// Area lights' shapes, for the shadow models that sample them: the point of a light for
// sample coordinates (s, t) in [0, 1)^2, uniform in area, as AreaLight::sample_point
// does in f64. The axes come scaled by the light's size, in voxel units (types.wgsl,
// `Light`). Contract: "Area lights".
#define_import_path voxlab::area_lights

#import voxlab::types::{Light, LIGHT_RECT, LIGHT_DISK}

const TAU: f32 = 6.283185307179586;

fn sample_point(light: Light, st: vec2<f32>) -> vec3<f32> {
    let c = light.position;
    if light.kind == LIGHT_RECT {
        // c + (s - 1/2) w u + (t - 1/2) h v
        return c + (st.x - 0.5) * light.axis_u + (st.y - 0.5) * light.axis_v;
    }
    let phi = TAU * st.y;
    if light.kind == LIGHT_DISK {
        // Polar mapping: r = R sqrt(s), phi = 2 pi t.
        return c + sqrt(st.x) * (cos(phi) * light.axis_u + sin(phi) * light.axis_v);
    }
    // Sphere surface (Archimedes' hat-box theorem): z = 1 - 2 s, phi = 2 pi t.
    let z = 1.0 - 2.0 * st.x;
    let r = sqrt(max(1.0 - z * z, 0.0));
    return c + r * cos(phi) * light.axis_u + r * sin(phi) * light.axis_v + z * light.axis_n;
}
