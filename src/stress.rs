//! The stress suite (`docs/stress.md`, issue 6): stiff and extreme cases rendered by the
//! GPU kernel (f32) and by the CPU reference (f64), with every pixel checked for being
//! finite and the GPU image compared with the oracle.
//!
//! Cases come from two places: the experiment files under `experiments/stress/`
//! (compiled in, so the suite does not depend on the working directory, and each can be
//! rendered alone with `voxlab render`), and cases generated here, where a case needs a
//! computed camera, a device limit or a grid no file should spell out.
//!
//! Tolerance: on the displayed value (radiance clamped to [0, 1], as in the PNG), a
//! pixel differs when any channel differs by more than 2/255. Some pixels are
//! ill-conditioned: their rays pass through voxel edges or corners (a lattice eye,
//! axis-aligned views), where f32 and f64 each pick one of the touching voxels and both
//! are right. The suite finds them by turning every primary ray of the oracle by
//! [`CONDITION_TURN`] either way; a pixel whose oracle value then changes beyond the
//! tolerance is counted apart. A case passes when both images are finite and at most
//! `max_bad` (0.5 %) of the other pixels differ.

use std::fmt::Write as _;
use std::time::Duration;

use anyhow::Result;
use glam::{DVec3, IVec3, UVec3};

use crate::experiment::Experiment;
use crate::frame::Frame;
use crate::gpu::GpuTracer;
use crate::metrics::{Domain, ImageDiff, compare};
use crate::render::RenderSettings;
use crate::scene::{
    AreaLight, AreaShape, Grid, Light, PointLight, Scene, seed_ids, seed_scene, seed_scene_dims,
};

/// A pixel differs from the oracle when a displayed channel differs by more than this.
pub const TOLERANCE: f64 = 2.0 / 255.0;

/// The camera turn (radians, either way) that tells ill-conditioned pixels: about 30
/// times the f32 rounding of a direction, so every ray that f32 can move across a voxel
/// edge or corner is caught, and a band of about 1e-4 voxels around the edges at the
/// distances of these scenes.
pub const CONDITION_TURN: f64 = 2e-6;

/// Fraction of differing pixels a case may have unless it states its own.
pub(crate) const DEFAULT_MAX_BAD: f64 = 0.005;

/// The stress experiment files, by name (file stem) and text.
pub const STRESS_FILES: &[(&str, &str)] = &[
    (
        "eye_on_lattice",
        include_str!("../experiments/stress/eye_on_lattice.toml"),
    ),
    (
        "camera_in_glass",
        include_str!("../experiments/stress/camera_in_glass.toml"),
    ),
    (
        "beer_lambert_thin",
        include_str!("../experiments/stress/beer_lambert_thin.toml"),
    ),
    (
        "beer_lambert_thick",
        include_str!("../experiments/stress/beer_lambert_thick.toml"),
    ),
    (
        "grid_17x9x24",
        include_str!("../experiments/stress/grid_17x9x24.toml"),
    ),
    (
        "far_origin_1e6",
        include_str!("../experiments/stress/far_origin_1e6.toml"),
    ),
];

/// One stress case: a scene, its settings, and how many differing pixels it may have.
#[derive(Clone, Debug)]
pub struct StressCase {
    pub name: String,
    /// What is stiff about it, in a few words.
    pub what: String,
    /// `experiments/stress/<file>.toml` or `generated`.
    pub source: String,
    pub scene: Scene,
    pub settings: RenderSettings,
    pub max_bad: f64,
}

/// What the generated cases depend on.
#[derive(Clone, Debug)]
pub struct SuiteOptions {
    /// The device's largest grid side (`GpuTracer::max_grid_side`): one case is a grid
    /// `max_grid_side x 8 x 8`.
    pub max_grid_side: u32,
    /// Side of the large cube case (the seed scene at N^3); `None` leaves it out.
    pub cube: Option<u32>,
}

impl Default for SuiteOptions {
    /// Lavapipe's limit, and no large cube (the tests' setting).
    fn default() -> Self {
        Self {
            max_grid_side: 4096,
            cube: None,
        }
    }
}

fn settings(width: u32, height: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        ..Default::default()
    }
}

fn seed16() -> Scene {
    seed_scene(16).expect("the seed scene at 16^3 is valid")
}

/// Points the orbit camera: `eye = target + distance (sin yaw cos pitch, sin pitch,
/// cos yaw cos pitch)`, exact for yaw = pitch = 0.
fn aim(scene: &mut Scene, target: DVec3, distance: f64, yaw_deg: f64, pitch_deg: f64, vfov: f64) {
    let c = &mut scene.camera;
    c.target = target;
    c.distance = distance;
    c.yaw = crate::settings::radians(yaw_deg);
    c.pitch = crate::settings::radians(pitch_deg);
    c.vfov = crate::settings::radians(vfov);
}

fn point(position: DVec3, color: DVec3, intensity: f64) -> Light {
    Light::Point(PointLight {
        position,
        color,
        intensity,
    })
}

fn case(name: &str, what: &str, scene: Scene, settings: RenderSettings) -> StressCase {
    StressCase {
        name: name.to_string(),
        what: what.to_string(),
        source: "generated".to_string(),
        scene,
        settings,
        max_bad: DEFAULT_MAX_BAD,
    }
}

/// A 32 x 8 x 32 grid with a solid floor (y = 0) under a glass layer (y = 1), two solid
/// pillars and a glass block on it.
fn slab_scene() -> Scene {
    let mut scene = seed16();
    let mut grid = Grid::new(UVec3::new(32, 8, 32), 1.0, DVec3::ZERO).unwrap();
    let fill = |g: &mut Grid, lo: IVec3, hi: IVec3, m: u8| {
        for z in lo.z..hi.z {
            for y in lo.y..hi.y {
                for x in lo.x..hi.x {
                    g.set(IVec3::new(x, y, z), m);
                }
            }
        }
    };
    fill(
        &mut grid,
        IVec3::ZERO,
        IVec3::new(32, 1, 32),
        seed_ids::SOLID,
    );
    fill(
        &mut grid,
        IVec3::new(0, 1, 0),
        IVec3::new(32, 2, 32),
        seed_ids::GLASS,
    );
    fill(
        &mut grid,
        IVec3::new(6, 2, 6),
        IVec3::new(8, 7, 8),
        seed_ids::SOLID,
    );
    fill(
        &mut grid,
        IVec3::new(20, 2, 10),
        IVec3::new(23, 6, 13),
        seed_ids::SOLID,
    );
    fill(
        &mut grid,
        IVec3::new(12, 2, 18),
        IVec3::new(18, 5, 22),
        seed_ids::SEMI_SOLID,
    );
    scene.grid = grid;
    scene.lights = vec![
        // Low: its light grazes the glass top at a few degrees.
        point(
            DVec3::new(-40.0, 2.5, 16.0),
            DVec3::new(1.0, 0.9, 0.8),
            4000.0,
        ),
        point(DVec3::new(16.0, 30.0, 20.0), DVec3::ONE, 1500.0),
    ];
    scene
}

/// The cases generated in code (the experiment files come on top, see [`cases`]).
///
/// One function because it is the suite's table of cases, each a few independent lines
/// (its scene, settings and what it stresses) in the order docs/stress.md lists them; the
/// scenes that cases share are the functions above.
pub fn generated_cases(opts: &SuiteOptions) -> Result<Vec<StressCase>> {
    let mut out = Vec::new();
    let c16 = DVec3::splat(8.0);

    // Axis-parallel rays: yaw 0, pitch 0 and an odd image give exactly zero x or y
    // components in the centre column and row; the centre ray runs along x = y = 8.
    let mut s = seed16();
    aim(&mut s, c16, 40.0, 0.0, 0.0, 36.87);
    out.push(case(
        "axis-parallel",
        "looking down -z, zero direction components",
        s,
        settings(65, 65),
    ));
    // Straight down the y axis: on the image diagonals |dx| == |dy| exactly, so those
    // rays run through voxel edges and which voxel a secondary ray starts in depends on
    // how its hit point rounds (f32 against f64): ill-conditioned pixels.
    let mut s = seed16();
    aim(&mut s, c16, 40.0, 0.0, 90.0, 36.87);
    out.push(case(
        "axis-down",
        "looking straight down -y (pitch 90)",
        s,
        settings(65, 65),
    ));
    // The eye exactly on the grid's corner (16, 16, 16), looking along its edge: rays
    // with dx, dy < 0 enter the corner voxel at t = 0 through an edge or the corner.
    let mut s = seed16();
    aim(&mut s, DVec3::new(16.0, 16.0, 0.0), 16.0, 0.0, 0.0, 90.0);
    out.push(case(
        "eye-on-grid-corner",
        "eye on the grid's corner, rays enter at t = 0",
        s,
        settings(65, 65),
    ));
    // The eye on the open front face's plane z = 16 (outside by the contract's `<`),
    // looking in: every ray enters the box at t = 0 through a face, edge or corner.
    let mut s = seed16();
    aim(&mut s, DVec3::new(8.0, 8.0, 0.0), 16.0, 0.0, 0.0, 90.0);
    out.push(case(
        "eye-on-grid-face",
        "eye on the grid's face plane z = 16",
        s,
        settings(65, 65),
    ));
    // Grazing: the eye on the glass layer's top plane y = 2, looking level: the lower
    // half of the image meets the glass at angles down to 0 (refraction near grazing),
    // the centre row runs in the plane itself; the low light grazes the glass too.
    let mut s = slab_scene();
    aim(&mut s, DVec3::new(16.0, 2.0, 16.0), 24.0, 30.0, 0.0, 50.0);
    out.push(case(
        "grazing",
        "eye in a face plane, rays and light grazing glass",
        s,
        settings(65, 65),
    ));
    // Inside the glass layer, looking slightly up: the glass -> void face is met beyond
    // the critical angle (total internal reflection) and near it.
    let mut s = slab_scene();
    aim(&mut s, DVec3::new(16.0, 1.5, 4.0), 20.0, 0.0, 2.0, 60.0);
    out.push(case(
        "inside-glass-tir",
        "eye inside a glass layer, TIR at grazing angles",
        s,
        settings(64, 64),
    ));
    // Inside a voxel: the eye in the semi-solid cube [7, 9)^3.
    let mut s = seed16();
    aim(&mut s, DVec3::new(8.3, 7.6, 7.95), 0.5, 0.0, 0.0, 90.0);
    out.push(case(
        "camera-in-voxel",
        "eye inside the semi-solid cube",
        s,
        settings(64, 64),
    ));
    // Outside looking away: the same eye as the seed's, turned around.
    let mut s = seed16();
    let eye = s.camera.eye();
    s.camera.target = eye + (eye - s.camera.target);
    s.camera.yaw += std::f64::consts::PI;
    s.camera.pitch = -s.camera.pitch;
    out.push(case(
        "looking-away",
        "eye outside the grid, looking away",
        s,
        settings(32, 32),
    ));
    // Lights inside occupied voxels: in the semi-solid cube and in a solid frame voxel.
    let mut s = seed16();
    s.lights = vec![
        point(c16 + DVec3::splat(0.25), DVec3::ONE, 50.0),
        point(DVec3::new(0.5, 0.5, 8.5), DVec3::new(1.0, 0.5, 0.2), 50.0),
        s.lights[0].clone(),
    ];
    out.push(case(
        "light-in-voxel",
        "lights inside a semi-solid and a solid voxel",
        s,
        settings(64, 64),
    ));
    // Lights at distance 0 from hit points: on the frame's corner (16, 16, 16) and on
    // the inner face of the back pane, where 1/d^2 is held by falloff_min_distance.
    let mut s = seed16();
    s.lights = vec![
        point(DVec3::new(16.0, 16.0, 16.0), DVec3::ONE, 30.0),
        point(DVec3::new(5.0, 5.0, 1.0), DVec3::new(0.3, 0.6, 1.0), 5.0),
    ];
    out.push(case(
        "light-on-surface",
        "lights at distance 0 from surfaces (falloff_min_distance)",
        s,
        settings(64, 64),
    ));
    // Far-away lights: 1e4 and 1e6 grid widths away, intensities scaled to match.
    let mut s = seed16();
    let w = s.grid.width();
    s.lights = vec![
        point(
            c16 + 1e4 * w * DVec3::new(0.3, 1.0, 0.6),
            DVec3::ONE,
            1e8 * w * w,
        ),
        point(
            c16 + 1e6 * w * DVec3::new(-0.5, 0.7, 1.0),
            DVec3::new(0.6, 0.7, 1.0),
            1e12 * w * w,
        ),
    ];
    out.push(case(
        "light-far",
        "lights 1e4 and 1e6 grid widths away",
        s,
        settings(64, 64),
    ));
    // Index of refraction 1 everywhere: refraction is a straight continuation.
    let mut s = seed16();
    for m in &mut s.materials {
        m.ior = 1.0;
    }
    out.push(case("ior-1", "ior 1.0 everywhere", s, settings(64, 64)));
    // Far above glass: total internal reflection inside glass and semi-solid.
    let mut s = seed16();
    s.materials[seed_ids::GLASS as usize].ior = 6.0;
    s.materials[seed_ids::SEMI_SOLID as usize].ior = 4.0;
    out.push(case(
        "ior-6-tir",
        "ior 6 and 4: total internal reflection",
        s,
        settings(64, 64),
    ));
    // Depth limits 0 and large. At 16/16 the total is bounded (max_depth): with the
    // limits apart, a glass tree grows with its mixed paths, and one frame of it is more
    // than lavapipe lets one invocation loop (shaders/counters.wgsl), so the largest
    // stack and limits are exercised under a total of 10.
    for (d, side, total) in [(0u32, 64u32, None), (8, 48, None), (16, 32, Some(10))] {
        let st = RenderSettings {
            max_reflection_depth: d,
            max_refraction_depth: d,
            max_depth: total,
            ..settings(side, side)
        };
        out.push(case(
            &format!("depth-{d}"),
            &match total {
                None => format!("reflection and refraction depth {d}/{d}"),
                Some(t) => format!("reflection and refraction depth {d}/{d}, total {t}"),
            },
            seed16(),
            st,
        ));
    }
    // The ray cutoff at its ends: 0 (the exact tree, deeper than the default), and 1,
    // where every ray below full weight is cut and a light is shaded only where its
    // bound reaches 1; and a cutoff among the weights total internal reflection grows
    // (kr + kt = 1.1 per bounce inside glass).
    for (name, what, cutoff, mut scene) in [
        (
            "ray-cutoff-0",
            "ray_cutoff 0: the whole tree, depth 8/8",
            0.0,
            seed16(),
        ),
        (
            "ray-cutoff-1",
            "ray_cutoff 1: full-weight rays only",
            1.0,
            seed16(),
        ),
        (
            "ray-cutoff-tir",
            "ray_cutoff 0.05 with ior 6: TIR chains",
            0.05,
            seed16(),
        ),
    ] {
        if name == "ray-cutoff-tir" {
            scene.materials[seed_ids::GLASS as usize].ior = 6.0;
        }
        let st = RenderSettings {
            ray_cutoff: cutoff,
            max_reflection_depth: 8,
            max_refraction_depth: 8,
            max_depth: Some(10),
            ..settings(48, 48)
        };
        out.push(case(name, what, scene, st));
    }
    // Soft shadows: a rectangle light under the reference shadow model (sampled area
    // lights), stratified samples over two frames, beer-lambert.
    let mut s = seed16();
    s.lights.push(Light::Area(AreaLight {
        emission: Default::default(),
        shape: AreaShape::Rect {
            width: 6.0,
            height: 4.0,
        },
        position: DVec3::new(8.0, 22.0, 12.0),
        normal: DVec3::NEG_Y,
        rotation: 0.3,
        color: DVec3::ONE,
        intensity: 300.0,
    }));
    let mut st = settings(48, 48);
    st.features.shadow_model = crate::technique::reference_shadow_model();
    st.features.transmittance = crate::technique::beer_lambert::ID;
    st.light_samples = 4;
    st.spp = 2;
    // (Each shadow model on this scene, the reference among them, is a case below.)
    // Every transmittance model (crate::technique::TRANSMITTANCES) on the same scene.
    for &m in crate::technique::TRANSMITTANCES {
        let mut st = st.clone();
        st.features.transmittance = crate::render::Transmittance(m);
        out.push(case(
            &format!("transmittance-{}", m.name),
            &format!(
                "transmittance {} on the rect area light: {}",
                m.name, m.summary
            ),
            s.clone(),
            st,
        ));
    }
    // Every shadow model (crate::technique) on the same scene: at its defaults,
    // and with the light shrunk to a point (its degenerate setting).
    for m in crate::technique::SHADOW_MODELS {
        let mut st = st.clone();
        st.features.set_shadow_model(m.name);
        out.push(case(
            &format!("shadow-{}", m.name),
            &format!(
                "shadow model {} on the rect area light: {}",
                m.name, m.summary
            ),
            s.clone(),
            st.clone(),
        ));
        let mut tiny = s.clone();
        for l in &mut tiny.lights {
            if let Light::Area(a) = l {
                a.shape = AreaShape::Rect {
                    width: 1e-9,
                    height: 1e-9,
                };
            }
        }
        out.push(case(
            &format!("shadow-{}-vanishing", m.name),
            &format!("shadow model {} with the area light shrunk to 1e-9", m.name),
            tiny,
            st,
        ));
    }
    // Many frames in one dispatch: every frame of a small image is one invocation
    // along the dispatch's z, so the image must not depend on how many there are (it
    // did when they were a loop in one invocation: Mesa's software driver cuts an
    // invocation's loops after 65535 iterations in all, shaders/counters.wgsl). The
    // largest image's frames take two dispatches, the second of one frame.
    for (side, spp, samples) in [(8u32, 256u32, 4u32), (32, 64, 8), (128, 65, 1)] {
        let mut s = seed16();
        let (c, w) = (s.grid.centre(), s.grid.width());
        for (k, shape) in [
            AreaShape::Rect {
                width: 5.0,
                height: 3.0,
            },
            AreaShape::Disk { radius: 2.0 },
            AreaShape::Sphere { radius: 1.5 },
        ]
        .into_iter()
        .enumerate()
        {
            let position = c + w * DVec3::new(0.6 * k as f64 - 0.6, 0.9, 0.8);
            s.lights.push(Light::Area(AreaLight {
                emission: Default::default(),
                shape,
                position,
                normal: (c - position).normalize(),
                rotation: 0.2,
                color: DVec3::ONE,
                intensity: 100.0,
            }));
        }
        let mut st = settings(side, side);
        st.features.shadow_model = crate::technique::reference_shadow_model();
        st.light_samples = samples;
        st.spp = spp;
        let per_dispatch = crate::gpu::frames_per_dispatch((side * side) as u64, spp);
        out.push(case(
            &format!("many-frames-{side}"),
            &format!(
                "{side}x{side}, {spp} frames ({per_dispatch} per dispatch), {samples} \
                 samples on each of 3 area lights"
            ),
            s,
            st,
        ));
    }
    // Cone tracing on odd, tiny and far-away grids: pyramids of odd sizes, a one-level
    // pyramid, a vanishing aperture, hemisphere cones with a range past the grid. Every
    // technique that reads the pyramids: the first such shadow model and every such
    // lighting term.
    let pyramid_model = crate::technique::SHADOW_MODELS
        .iter()
        .copied()
        .find(|m| m.pyramid)
        .expect("a shadow model reads the cone pyramids");
    let pyramid_terms = || {
        crate::technique::LIGHTING_TERMS
            .iter()
            .copied()
            .filter(|t| t.pyramid)
    };
    let all_cones = |st: &mut RenderSettings| {
        st.features.shadow_model = pyramid_model;
        for t in pyramid_terms() {
            st.features.set_term(t.name, true);
        }
    };
    let mut st = settings(48, 48);
    all_cones(&mut st);
    out.push(case(
        "cones-17x9x24",
        "cone shadows, AO and indirect on an odd, non-cubic grid (odd pyramid levels)",
        seed_scene_dims(UVec3::new(17, 9, 24))?,
        st,
    ));
    let mut st = settings(32, 32);
    all_cones(&mut st);
    out.push(case(
        "cones-1x1x1",
        "every cone feature on a one-voxel grid (a one-level pyramid)",
        seed_scene_dims(UVec3::ONE)?,
        st,
    ));
    let mut st = settings(48, 48);
    st.features.shadow_model = pyramid_model;
    st.cones.aperture_deg = 1e-3;
    st.cones.step_factor = 0.05;
    out.push(case(
        "cones-vanishing",
        "cone shadows with a 0.001-degree aperture and tiny steps (many samples per cone)",
        seed16(),
        st,
    ));
    let mut st = settings(48, 48);
    for t in pyramid_terms().filter(|t| !t.radiance_pyramid) {
        st.features.set_term(t.name, true);
    }
    st.cones.ao_range = 1e4;
    st.cones.start_offset = 0.0;
    out.push(case(
        "cones-ao-far",
        "AO cones with a range far past the grid and no start offset",
        seed16(),
        st,
    ));
    let mut s = seed16();
    s.grid = crate::scene::seed::seed_grid(UVec3::splat(16), 1.0, DVec3::new(1e6, -1e6, 1e6))?;
    let (c, w) = (s.grid.centre(), s.grid.width());
    s.lights = crate::scene::seed::seed_lights(c, w);
    s.camera = crate::scene::seed::seed_camera(c, w);
    let mut st = settings(48, 48);
    all_cones(&mut st);
    out.push(case(
        "cones-far-origin",
        "every cone feature with the grid at (1e6, -1e6, 1e6)",
        s,
        st,
    ));
    // Grids: one voxel; the device's longest side.
    out.push(case(
        "grid-1x1x1",
        "a grid of one voxel",
        seed_scene_dims(UVec3::ONE)?,
        settings(32, 32),
    ));
    let side = opts.max_grid_side;
    let mut s = seed_scene_dims(UVec3::new(side, 8, 8))?;
    // Looking down the tube from beyond its +x end, through the pane's hole: primary
    // rays walk the whole length before they meet the far pane.
    let len = side as f64;
    aim(
        &mut s,
        DVec3::new(0.5 * len, 4.0, 4.0),
        0.5 * len + 12.0,
        90.0,
        0.0,
        20.0,
    );
    out.push(case(
        &format!("grid-{side}x8x8"),
        "longest side = max_texture_dimension_3d (the cone pyramids' limit)",
        s,
        settings(48, 48),
    ));
    if let Some(n) = opts.cube {
        out.push(case(
            &format!("grid-{n}^3"),
            "a large cube (the seed scene at N^3)",
            seed_scene(n)?,
            settings(32, 32),
        ));
    }
    // Far from the origin (1e6 is an experiment file).
    let mut s = seed16();
    let origin = DVec3::new(1e5, 1e5, -1e5);
    s.grid = crate::scene::seed::seed_grid(UVec3::splat(16), 1.0, origin)?;
    let (c, w) = (s.grid.centre(), s.grid.width());
    s.lights = crate::scene::seed::seed_lights(c, w);
    s.camera = crate::scene::seed::seed_camera(c, w);
    out.push(case(
        "far-origin-1e5",
        "seed scene with the grid at (1e5, 1e5, -1e5)",
        s,
        settings(64, 64),
    ));
    Ok(out)
}

/// The cases of the experiment files under `experiments/stress/`.
pub(crate) fn file_cases() -> Result<Vec<StressCase>> {
    STRESS_FILES
        .iter()
        .map(|(stem, text)| {
            let path = format!("experiments/stress/{stem}.toml");
            let e = Experiment::from_str(text, &path)?;
            let what = description(text).unwrap_or_else(|| e.name.clone());
            Ok(StressCase {
                name: e.name,
                what,
                source: path,
                scene: e.scene,
                settings: e.settings,
                max_bad: DEFAULT_MAX_BAD,
            })
        })
        .collect()
}

/// The `description = "..."` line of an experiment file (the loader keeps it for the
/// reader only).
fn description(text: &str) -> Option<String> {
    let v: toml::Table = toml::from_str(text).ok()?;
    v.get("description")?.as_str().map(str::to_string)
}

/// Every case: the files first, then the generated ones.
pub fn cases(opts: &SuiteOptions) -> Result<Vec<StressCase>> {
    let mut all = file_cases()?;
    all.extend(generated_cases(opts)?);
    Ok(all)
}

/// What the GPU made of a case.
#[derive(Clone, Debug)]
pub enum GpuResult {
    Rendered {
        frame: Frame,
        time: Duration,
    },
    /// The kernel refused a feature it does not implement (the suite picks the case up
    /// once it does).
    Unsupported(String),
    /// Any other error.
    Failed(String),
    /// No adapter was given to the suite.
    NoAdapter,
}

/// One row of the table.
#[derive(Clone, Debug)]
pub struct StressRow {
    pub name: String,
    pub what: String,
    pub source: String,
    pub image: (u32, u32),
    pub grid: UVec3,
    /// Bytes of the grid on the device (an R8Uint 3D texture: one per voxel).
    pub grid_bytes: u64,
    pub cpu_finite: bool,
    pub cpu_time: Duration,
    pub gpu: GpuResult,
    /// GPU against CPU, displayed values, threshold [`TOLERANCE`].
    pub diff: Option<ImageDiff>,
    /// Pixels where the oracle itself is unstable: turning the camera by
    /// [`CONDITION_TURN`] radians either way changes the CPU image there beyond
    /// [`TOLERANCE`] (rays through voxel edges and corners, where f32 and f64 may pick
    /// different voxels and both be right).
    pub ill_conditioned: usize,
    /// Pixels beyond [`TOLERANCE`] among the others: these are the tracer's errors.
    pub over_well_conditioned: usize,
    /// Mean FLIP error (nv-flip) of the GPU image against the oracle's.
    pub flip_mean: Option<f64>,
    pub max_bad: f64,
    /// The render plan's flags and ray stack (the kernel variant that rendered it).
    pub plan: String,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    Pass,
    /// The GPU does not implement a feature of the case; the CPU image was checked.
    Unsupported,
    Fail(String),
}

impl StressRow {
    pub(crate) fn gpu_finite(&self) -> Option<bool> {
        match &self.gpu {
            GpuResult::Rendered { frame, .. } => Some(frame.all_finite()),
            _ => None,
        }
    }

    pub fn verdict(&self) -> Verdict {
        if !self.cpu_finite {
            return Verdict::Fail("CPU image not finite".into());
        }
        match &self.gpu {
            GpuResult::Unsupported(_) => return Verdict::Unsupported,
            GpuResult::Failed(e) => return Verdict::Fail(format!("GPU error: {e}")),
            GpuResult::NoAdapter => return Verdict::Fail("no GPU adapter".into()),
            GpuResult::Rendered { .. } => {}
        }
        if self.gpu_finite() != Some(true) {
            return Verdict::Fail("GPU image not finite".into());
        }
        let n = (self.image.0 as usize * self.image.1 as usize).max(1);
        let frac = self.over_well_conditioned as f64 / n as f64;
        if frac > self.max_bad {
            return Verdict::Fail(format!(
                "{:.2} % of well-conditioned pixels over {}/255 (limit {} %)",
                100.0 * frac,
                (TOLERANCE * 255.0).round(),
                100.0 * self.max_bad
            ));
        }
        Verdict::Pass
    }

    fn verdict_text(&self) -> String {
        match self.verdict() {
            Verdict::Pass => "pass".into(),
            Verdict::Unsupported => "GPU: unsupported".into(),
            Verdict::Fail(why) => format!("FAIL: {why}"),
        }
    }
}

/// A GPU error that only says a feature is missing from the kernel.
fn is_unsupported(message: &str) -> bool {
    let m = message.to_lowercase();
    m.contains("does not implement") || m.contains("unsupported") || m.contains("not supported")
}

/// Renders one case on both backends and compares.
pub fn run_case(gpu: Option<&mut GpuTracer>, case: &StressCase) -> StressRow {
    let cpu = crate::cpu::render(&case.scene, &case.settings);
    let unstable = ill_conditioned(case, &cpu.frame);
    let gpu_result = match gpu {
        None => GpuResult::NoAdapter,
        // The first dispatch of a kernel variant includes the driver's compile on some
        // drivers (lavapipe JITs there): a warm-up render first, then the timed one.
        Some(t) => match t
            .render(&case.scene, &case.settings)
            .and_then(|_| t.render(&case.scene, &case.settings))
        {
            Ok(out) => GpuResult::Rendered {
                frame: out.frame,
                // Device time where the adapter has timestamp queries.
                time: t.last_gpu_time().unwrap_or(out.trace_time),
            },
            Err(e) => {
                let msg = format!("{e:#}");
                if is_unsupported(&msg) {
                    GpuResult::Unsupported(msg)
                } else {
                    GpuResult::Failed(msg)
                }
            }
        },
    };
    let diff = match &gpu_result {
        GpuResult::Rendered { frame, .. } => compare(frame, &cpu.frame, Domain::Display, TOLERANCE),
        _ => None,
    };
    let over_well_conditioned = match &gpu_result {
        GpuResult::Rendered { frame, .. } => over_well_conditioned(frame, &cpu.frame, &unstable),
        _ => 0,
    };
    let flip = match &gpu_result {
        GpuResult::Rendered { frame, .. } => Some(flip_mean(&cpu.frame, frame)),
        _ => None,
    };
    let dims = case.scene.grid.dims();
    let plan = crate::plan::Plan::new(&case.scene, &case.settings);
    let flags = plan.flags_on();
    StressRow {
        name: case.name.clone(),
        what: case.what.clone(),
        source: case.source.clone(),
        image: (case.settings.width, case.settings.height),
        grid: dims,
        grid_bytes: case.scene.grid.voxel_count() as u64,
        cpu_finite: cpu.frame.all_finite(),
        cpu_time: cpu.trace_time,
        gpu: gpu_result,
        diff,
        ill_conditioned: unstable.iter().filter(|&&u| u).count(),
        over_well_conditioned,
        flip_mean: flip,
        max_bad: case.max_bad,
        plan: format!("{} (stack {})", flags.join(" "), plan.ray_stack_size),
    }
}

pub use crate::metrics::flip_mean;

/// The pixels of `image` over [`TOLERANCE`] from `oracle` that `unstable`
/// ([`ill_conditioned`]) does not mark: what the stress suite's verdict counts.
pub fn over_well_conditioned(image: &Frame, oracle: &Frame, unstable: &[bool]) -> usize {
    image
        .pixels
        .iter()
        .zip(&oracle.pixels)
        .zip(unstable)
        .filter(|((g, c), u)| !**u && pixel_diff(g, c) > TOLERANCE)
        .count()
}

/// Largest displayed-channel difference of two pixels (NaN counts as infinite).
fn pixel_diff(a: &[f32; 3], b: &[f32; 3]) -> f64 {
    (0..3)
        .map(|c| {
            let d = (a[c].clamp(0.0, 1.0) as f64 - b[c].clamp(0.0, 1.0) as f64).abs();
            if d.is_nan() { f64::INFINITY } else { d }
        })
        .fold(0.0, f64::max)
}

/// Which pixels of the oracle move beyond [`TOLERANCE`] when every primary ray turns by
/// [`CONDITION_TURN`] one way or the other. The eye stays exactly where it is (so its
/// medium does too): the rays are traced from it with the reference's `trace_ray`.
pub fn ill_conditioned(case: &StressCase, oracle: &Frame) -> Vec<bool> {
    let (w, h) = (case.settings.width, case.settings.height);
    ill_conditioned_region(
        &case.scene,
        &case.settings,
        (0..w, 0..h),
        oracle,
        CONDITION_TURN,
    )
}

/// [`ill_conditioned`] for the pixels `columns` x `rows` of the image, `oracle` their
/// reference (a crop, rows from the top), under a turn of `turn` radians: what
/// `render --check` asks of a crop that differs. Pixels at their centres, without a
/// pixel filter's offsets.
pub fn ill_conditioned_region(
    scene: &Scene,
    settings: &crate::render::RenderSettings,
    (columns, rows): (std::ops::Range<u32>, std::ops::Range<u32>),
    oracle: &Frame,
    turn: f64,
) -> Vec<bool> {
    use rayon::prelude::*;
    let cam = scene.camera.frame();
    let (w, h) = (settings.width, settings.height);
    // Across the view, and generic so it does not run along a lattice axis.
    let across = (0.8 * cam.right + 0.6 * cam.up) * turn;
    let plan = crate::plan::Plan::new(scene, settings);
    let frames = plan.frames(settings);
    // Once for the image: `trace_ray` would derive the plan (a scan of the grid) per ray.
    let prepared = crate::cpu::Prepared::new(scene, settings, &plan);
    let prepared = &prepared;
    let (x0, y0) = (columns.start, rows.start);
    rows.into_par_iter()
        .flat_map_iter(|j| {
            let mut stats = crate::RayStats::default();
            columns
                .clone()
                .map(move |i| {
                    let dir = cam.primary_dir(i, j, w, h);
                    let mut unstable = false;
                    for sign in [-1.0, 1.0] {
                        let d = (dir + sign * across).normalize();
                        let mut sum = DVec3::ZERO;
                        for frame in 0..frames {
                            let key = crate::sampling::SampleKey {
                                pixel: j * w + i,
                                frame,
                            };
                            sum += crate::cpu::trace_ray_with(
                                scene, settings, prepared, key, cam.eye, d, &mut stats,
                            );
                        }
                        let c = sum / frames as f64;
                        let p = [c.x as f32, c.y as f32, c.z as f32];
                        unstable |= pixel_diff(&p, &oracle.get(i - x0, j - y0)) > TOLERANCE;
                    }
                    unstable
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Runs every case, calling `progress` after each.
pub fn run(
    mut gpu: Option<&mut GpuTracer>,
    cases: &[StressCase],
    mut progress: impl FnMut(&StressRow),
) -> Vec<StressRow> {
    cases
        .iter()
        .map(|c| {
            let row = run_case(gpu.as_deref_mut(), c);
            progress(&row);
            row
        })
        .collect()
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn finite_text(f: Option<bool>) -> &'static str {
    match f {
        Some(true) => "yes",
        Some(false) => "NO",
        None => "-",
    }
}

/// The columns of both tables.
const HEADER: [&str; 17] = [
    "case",
    "what",
    "image",
    "grid",
    "grid bytes",
    "CPU finite",
    "GPU finite",
    "px > 2/255",
    "ill-cond px",
    "well-cond px > 2/255",
    "max diff",
    "mean diff",
    "FLIP mean",
    "GPU ms",
    "CPU ms",
    "verdict",
    "plan",
];

fn cells(r: &StressRow, markdown: bool) -> Vec<String> {
    let gpu_ms = match &r.gpu {
        GpuResult::Rendered { time, .. } => format!("{:.2}", ms(*time)),
        _ => "-".into(),
    };
    let (over, max, mean) = match r.diff {
        Some(d) => (
            if markdown {
                format!("{} ({:.2} %)", d.pixels_over, 100.0 * d.fraction_over())
            } else {
                d.pixels_over.to_string()
            },
            format!("{:.2e}", d.max_abs),
            format!("{:.2e}", d.mean_abs),
        ),
        None => ("-".into(), "-".into(), "-".into()),
    };
    vec![
        r.name.clone(),
        r.what.clone(),
        format!("{}x{}", r.image.0, r.image.1),
        format!("{}x{}x{}", r.grid.x, r.grid.y, r.grid.z),
        if markdown {
            crate::output::bytes_text(r.grid_bytes)
        } else {
            r.grid_bytes.to_string()
        },
        finite_text(Some(r.cpu_finite)).into(),
        finite_text(r.gpu_finite()).into(),
        over,
        r.ill_conditioned.to_string(),
        if r.diff.is_some() {
            r.over_well_conditioned.to_string()
        } else {
            "-".into()
        },
        max,
        mean,
        r.flip_mean
            .map(|f| format!("{f:.4}"))
            .unwrap_or_else(|| "n/a".into()),
        gpu_ms,
        format!("{:.2}", ms(r.cpu_time)),
        r.verdict_text(),
        r.plan.clone(),
    ]
}

/// The table as markdown, with a header naming the device and the tolerance.
pub fn markdown(rows: &[StressRow], adapter: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Stress suite: GPU `{adapter}` (f32) against the CPU reference (f64).\n\
         A pixel differs when a displayed channel (clamped to [0, 1]) differs by more \
         than 2/255; a case passes when both images are finite and at most 0.5 % of its \
         well-conditioned pixels differ. max/mean diff are absolute differences per channel on displayed values. \
         FLIP: mean of NVIDIA FLIP (nv-flip, 8-bit displayed images, 67 px/degree). \
         ill-cond px: pixels where the oracle itself changes beyond 2/255 when every \
         primary ray turns by 2e-6 rad either way (rays through voxel edges and corners, \
         where f32 and f64 may each pick a different, equally right voxel); the verdict \
         counts the differing pixels among the others. \
         Times: the trace alone, after a warm-up render (uploads excluded).\n"
    );
    let _ = writeln!(s, "| {} |", HEADER.join(" | "));
    let _ = writeln!(s, "|{}", "---|".repeat(HEADER.len()));
    for r in rows {
        let c: Vec<String> = cells(r, true)
            .into_iter()
            .map(|x| x.replace('|', "\\|"))
            .collect();
        let _ = writeln!(s, "| {} |", c.join(" | "));
    }
    let fails = rows
        .iter()
        .filter(|r| matches!(r.verdict(), Verdict::Fail(_)))
        .count();
    let unsupported = rows
        .iter()
        .filter(|r| r.verdict() == Verdict::Unsupported)
        .count();
    let _ = writeln!(
        s,
        "\n{} cases: {} pass, {} GPU-unsupported, {} fail.",
        rows.len(),
        rows.len() - fails - unsupported,
        unsupported,
        fails
    );
    s
}

fn csv_field(x: &str) -> String {
    if x.contains([',', '"', '\n']) {
        format!("\"{}\"", x.replace('"', "\"\""))
    } else {
        x.to_string()
    }
}

/// The table as CSV (plain numbers: bytes, pixel counts, milliseconds).
pub fn csv(rows: &[StressRow]) -> String {
    let mut s = String::new();
    let names: Vec<String> = HEADER
        .iter()
        .map(|h| {
            h.replace("px > 2/255", "pixels_over_2_255")
                .replace("diff", "abs_diff")
                .replace(' ', "_")
                .to_lowercase()
        })
        .collect();
    let _ = writeln!(s, "{},max_bad_fraction,source", names.join(","));
    for r in rows {
        let mut c: Vec<String> = cells(r, false).iter().map(|x| csv_field(x)).collect();
        c.push(r.max_bad.to_string());
        c.push(csv_field(&r.source));
        let _ = writeln!(s, "{}", c.join(","));
    }
    s
}

/// Writes `stress.md` and `stress.csv` into `dir` (created if missing, and removed again
/// if the write fails); returns their paths.
pub fn write_tables(
    dir: &std::path::Path,
    rows: &[StressRow],
    adapter: &str,
    record: &serde_json::Value,
) -> Result<(std::path::PathBuf, std::path::PathBuf)> {
    use crate::output::{bytes_fill, sidecar_path, write_together};
    let md = dir.join("stress.md");
    let cs = dir.join("stress.csv");
    let (md_text, cs_text) = (markdown(rows, adapter), csv(rows));
    let record = serde_json::to_string_pretty(record)?;
    let (md_json, cs_json) = (sidecar_path(&md), sidecar_path(&cs));
    // The tables and their records, all four or none.
    write_together(vec![
        (md.clone(), bytes_fill(&md, md_text.as_bytes())),
        (cs.clone(), bytes_fill(&cs, cs_text.as_bytes())),
        (md_json.clone(), bytes_fill(&md_json, record.as_bytes())),
        (cs_json.clone(), bytes_fill(&cs_json, record.as_bytes())),
    ])?;
    Ok((md, cs))
}
