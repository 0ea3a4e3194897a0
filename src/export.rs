//! Export to an independent reference renderer: an experiment's scene as a Mitsuba 3
//! scene (`scene.xml` and binary PLY meshes), so a voxlab estimate can be measured
//! against a renderer the literature trusts (`voxlab export EXPERIMENT --to mitsuba DIR`,
//! docs/mitsuba.md).
//!
//! What maps exactly, and what only approximately ([`Approximation`], refused under
//! `strict`):
//! - Geometry: the voxels' faces between different media, merged per material and
//!   direction into maximal rectangles (greedy meshing, M. Lysenko, "Meshing in a
//!   Minecraft Game", 2012), wound counter-clockwise seen from the side the face is
//!   seen from; or, when the experiment traces triangles, its triangles with their
//!   shading normals. Exact.
//! - Units: voxlab's diffuse term is `kd albedo E (n . l)` (Phong as the seed writes it,
//!   no `1 / pi`), Mitsuba's `diffuse` BSDF is `rho / pi`: every emitter is exported
//!   `pi` times brighter, and `rho = kd albedo`. Every path of the Whitted model has one
//!   diffuse connection, so this is exact.
//! - Lights: a point light is Mitsuba's `point` (intensity `pi I c`); a Lambertian rect
//!   or disk is a `rectangle` or `disk` with an `area` emitter of radiance
//!   `pi I c / A`, facing the same way. Exact (with falloff on, beyond `d_min`). An
//!   isotropic rect or disk has no Mitsuba equivalent: it becomes the Lambertian
//!   emitter with the power its front half sends (`L = 2 pi I c / A`); a sphere light
//!   (isotropic in voxlab) a Lambertian `sphere` that lights an unoccluded point alike
//!   (`L = pi I c / R^2`) but casts a different penumbra. Mitsuba's emitter shapes stop
//!   shadow rays, voxlab's lights do not: a light whose shape may stand between the
//!   scene and another light is approximated (`emitter_shapes`).
//! - Materials: diffuse (`kr = kt = 0`) is `diffuse`; a mirror (`kd = 0`, `kt = 0`) a
//!   `conductor` of `specular_reflectance = kr`; diffuse plus mirror a `blendbsdf` of
//!   the two when `kd + kr <= 1`. Exact. A Phong highlight (`ks > 0`) is dropped, and a
//!   transparent material (`kt > 0`) is a `dielectric` of its `ior` with
//!   `specular_reflectance = kr`, `specular_transmittance = kt` and, under a
//!   transmittance model with distance in it (`TransmittanceModel::interior_extinction`:
//!   Beer-Lambert), a homogeneous absorbing interior (then the integrator is `volpath`).
//!   Exact when the material is `dielectric = "fresnel"`, meets only void, and shadows
//!   stop at it (`transmittance = "opaque"`, as Mitsuba's do); a diffuse term makes it a
//!   `blendbsdf` of diffuse and dielectric, exact while `kd max(albedo) + max(kr, kt)
//!   <= 1`. Otherwise each difference is an approximation (`Writer::dielectric`).
//! - Camera: `perspective` at the orbit camera's eye, target and up, the vertical field
//!   of view, the image's size; pixel `(i, j)` covers the same square. voxlab's
//!   `pixel_filter = "box"` (`filter_width = 0.5`) is Mitsuba's `box` filter exactly;
//!   pixel centres (`"none"`) and other filters are approximated by the box.
//! - Integrator: `path` (`volpath` when a glass has an absorbing interior) with `max_depth = 2` (direct light only, as the Whitted model
//!   lights a diffuse hit) and `hide_emitters` (voxlab's lights are not seen). A scene
//!   with mirrors or glass needs longer paths, which also carry the diffuse
//!   interreflection voxlab leaves out: an approximation. `scene.xml.json` records the
//!   Whitted tree's depth limits, from which `voxlab.mitsuba.Whitted` (python) renders
//!   Whitted's paths alone in Mitsuba.
//! - Left out, as approximations: the ambient term, emissive voxels (voxlab shows them
//!   and they light nothing), the lighting terms (AO, indirect), falloff turned off,
//!   `d_min` where a light comes within it of a surface.

use std::fmt::Write as _;
use std::path::PathBuf;

use glam::{DVec3, IVec3};

use crate::experiment::Experiment;
use crate::input::short_number;
use crate::render::PixelFilter;
use crate::scene::{AreaLight, AreaShape, Dielectric, Emission, Grid, Light, Material, VOID};
use crate::surface::SurfaceMesh;

mod emitter_shapes;

/// A part of the scene Mitsuba cannot hold exactly, and what the export does instead.
#[derive(Clone, Debug, PartialEq)]
pub struct Approximation {
    /// The experiment's key it comes from (`lights[0].emission`, `materials[glass].ks`).
    pub key: String,
    /// What the export writes instead, and what differs.
    pub mapping: String,
}

/// Files of a Mitsuba scene, relative to the scene's directory, and the approximations
/// made (each also a comment in `scene.xml`).
#[derive(Clone, Debug, Default)]
pub struct MitsubaScene {
    pub files: Vec<(PathBuf, Vec<u8>)>,
    pub approximations: Vec<Approximation>,
    /// Triangles written, over every mesh.
    pub triangles: usize,
}

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error(
        "{file}: --strict: {count} part(s) of the scene have no exact Mitsuba equivalent:\n{list}"
    )]
    Strict {
        file: String,
        count: usize,
        list: String,
    },
    #[error("{file}: the scene's triangles: {message}")]
    Triangles { file: String, message: String },
    #[error("{file}: {what}")]
    TooLarge { file: String, what: String },
    #[error("{file}: {key}: {what}")]
    OutOfRange {
        file: String,
        key: String,
        what: String,
    },
}

/// An export's refusal as the facade's error, with its file and, for a value Mitsuba
/// cannot hold, its key.
impl From<ExportError> for crate::Error {
    fn from(e: ExportError) -> Self {
        use crate::error::ErrorKind;
        let message = e.to_string();
        let (kind, file, key) = match e {
            ExportError::Strict { file, .. } => (ErrorKind::Invalid, file, None),
            ExportError::Triangles { file, .. } | ExportError::TooLarge { file, .. } => {
                (ErrorKind::Scene, file, None)
            }
            ExportError::OutOfRange { file, key, .. } => (ErrorKind::Invalid, file, Some(key)),
        };
        crate::Error::new(kind, message).located(file, key)
    }
}

/// Voxels of the largest grid exported: the faces are found by visiting every voxel
/// (six passes), which stays within seconds up to here.
pub(crate) const MAX_EXPORT_VOXELS: u64 = 1 << 27;
/// Triangles of the largest export (~0.6 GB of PLY): a grid whose faces would need more
/// (a checkerboard of materials, say) is refused before anything is written.
pub(crate) const MAX_EXPORT_TRIANGLES: usize = 1 << 24;

/// The Mitsuba 3 scene of `e` (module documentation). With `strict`, any
/// approximation is an error listing them all.
pub fn mitsuba(e: &Experiment, strict: bool) -> Result<MitsubaScene, ExportError> {
    let file = e
        .source_path
        .as_ref()
        .map_or_else(|| e.name.clone(), |p| p.display().to_string());
    let d = e.scene.grid.dims().as_u64vec3();
    let voxels = d.x * d.y * d.z;
    if voxels > MAX_EXPORT_VOXELS {
        return Err(ExportError::TooLarge {
            file,
            what: format!(
                "a grid of {}x{}x{} = {voxels} voxels; export visits every voxel and takes \
                 grids of at most {MAX_EXPORT_VOXELS}",
                d.x, d.y, d.z
            ),
        });
    }
    let mut w = Writer {
        e,
        used: used_materials(&e.scene.grid),
        emitter_shapes: Vec::new(),
        file,
        xml: String::new(),
        out: MitsubaScene::default(),
    };
    let _ = writeln!(
        w.xml,
        "<!-- voxlab export of {}: docs/mitsuba.md -->",
        esc(&w.file)
    );
    let _ = writeln!(w.xml, "<scene version=\"3.0.0\">");
    w.integrator();
    w.materials()?;
    let meshes = w.geometry()?;
    let quads: Vec<[DVec3; 3]> = meshes
        .iter()
        .flat_map(|(_, t, _)| t.iter().copied())
        .collect();
    // After the geometry: the sensor's clipping range is the scene's.
    w.camera(&quads)?;
    for (j, light) in e.scene.lights.iter().enumerate() {
        w.light(j, light, &quads)?;
    }
    w.emitters_in_the_way(&quads);
    let Writer {
        file,
        mut xml,
        mut out,
        ..
    } = w;
    for a in &out.approximations {
        let _ = writeln!(
            xml,
            "  <!-- approximation: {}: {} -->",
            esc(&a.key),
            esc(&a.mapping)
        );
    }
    let _ = writeln!(xml, "</scene>");
    if strict && !out.approximations.is_empty() {
        let list = out
            .approximations
            .iter()
            .map(|a| format!("  {}: {}", a.key, a.mapping))
            .collect::<Vec<_>>()
            .join("\n");
        return Err(ExportError::Strict {
            file,
            count: out.approximations.len(),
            list,
        });
    }
    out.files
        .insert(0, (PathBuf::from("scene.xml"), xml.into_bytes()));
    Ok(out)
}

/// An export under way: `scene.xml` so far, the files beside it and the
/// approximations made, written part by part (integrator, camera, materials, geometry,
/// lights).
struct Writer<'a> {
    e: &'a Experiment,
    /// The experiment's file, as errors name it.
    file: String,
    /// Which materials some voxel holds.
    used: [bool; 256],
    /// The lights written as Mitsuba shapes (rectangle, disk, sphere), by index.
    emitter_shapes: Vec<usize>,
    xml: String,
    out: MitsubaScene,
}

impl Writer<'_> {
    fn approx(&mut self, key: &str, mapping: String) {
        self.out.approximations.push(Approximation {
            key: key.to_string(),
            mapping,
        })
    }

    /// A transparent material whose transmittance model has a distance in it gets a
    /// homogeneous absorbing interior, which Mitsuba's volumetric path tracer reads.
    fn interior(&self, m: &Material) -> Option<DVec3> {
        let transmittance = self.e.settings.features.transmittance.model();
        (m.kt > 0.0)
            .then(|| (transmittance.interior_extinction)(m, self.e.scene.grid.voxel_size()))
            .flatten()
    }

    /// The approximations of a transparent material `m` as Mitsuba's `dielectric` of
    /// `specular_reflectance = kr`, `specular_transmittance = kt` (blended with a
    /// diffuse term where it has one): exact when it splits its rays by Fresnel's
    /// equations, its blend fits, it meets only void (Mitsuba's exterior is vacuum) and
    /// shadows stop at it (`opaque`), as a path tracer's do.
    fn dielectric(&mut self, m: &Material) {
        let key = |k: &str| format!("materials[{}].{k}", m.name);
        if m.dielectric != Dielectric::Fresnel {
            self.approx(
                &key("dielectric"),
                format!(
                    "fixed kr and kt as Mitsuba's dielectric (ior {}), which weights reflection \
                     and refraction by Fresnel's equations (dielectric = \"fresnel\" is exact)",
                    m.ior
                ),
            );
        }
        if m.kd > 0.0 && diffuse_dielectric_blend(m).is_none() {
            self.approx(
                &key("kd"),
                format!(
                    "kd max(albedo) + max(kr, kt) = {} > 1: the blend of diffuse and \
                     dielectric is scaled to fit",
                    m.kd * m.albedo.max_element() + m.kr.max(m.kt)
                ),
            );
        }
        if m.ior == 1.0 {
            self.approx(
                &key("ior"),
                "ior 1 as 1.000001: Mitsuba's dielectric needs two different indices".into(),
            );
        }
        let model = self.e.settings.features.transmittance;
        if model != crate::technique::opaque::ID {
            let absorbs = self.interior(m).is_some();
            self.approx(
                "features.transmittance",
                format!(
                    "{}: voxlab's shadow rays pass through {}, Mitsuba's stop at a dielectric \
                     (transmittance = \"opaque\" is exact){}",
                    model.name(),
                    m.name,
                    if absorbs {
                        "; its paths inside the glass are also absorbed in Mitsuba (a medium), \
                         not in voxlab, whose kt weighs each crossing"
                    } else {
                        ""
                    }
                ),
            );
        }
    }

    /// Direct light only unless specular chains are needed.
    fn integrator(&mut self) {
        let (scene, s) = (&self.e.scene, &self.e.settings);
        let specular = scene
            .materials
            .iter()
            .enumerate()
            .any(|(i, m)| i != VOID as usize && self.used[i] && (m.kr > 0.0 || m.kt > 0.0));
        let media = scene
            .materials
            .iter()
            .enumerate()
            .any(|(i, m)| i != VOID as usize && self.used[i] && self.interior(m).is_some());
        let depth = if specular {
            self.approx(
                "materials",
                "mirrors or glass: Mitsuba's path tracer follows them to max_depth and also \
             carries the diffuse interreflection that voxlab's Whitted model leaves out \
             (voxlab.mitsuba.Whitted, from Python, renders the Whitted paths alone)"
                    .into(),
            );
            2 + s.max_reflection_depth + s.max_refraction_depth
        } else {
            2
        };
        let _ = writeln!(
            self.xml,
            "  <integrator type=\"{}\">\n    <integer name=\"max_depth\" value=\"{depth}\"/>\n    \
         <boolean name=\"hide_emitters\" value=\"true\"/>\n  </integrator>",
            if media { "volpath" } else { "path" }
        );
    }

    /// The sensor, which sees the triangles `tris`.
    fn camera(&mut self, tris: &[[DVec3; 3]]) -> Result<(), ExportError> {
        let (scene, s) = (&self.e.scene, &self.e.settings);
        let f = scene.camera.frame();
        let (near, far, nearest) = clip_range(f.eye, tris);
        let clipped = nearest < near;
        let eye = f.eye.abs().max_element();
        if eye.max(far) > f32::MAX as f64 {
            return Err(ExportError::OutOfRange {
                file: self.file.clone(),
                key: "camera.distance".into(),
                what: format!(
                    "the eye, {eye:.3e} from the origin and {far:.3e} from the farthest \
                     surface, is beyond Mitsuba's 32-bit floats (at most {:e})",
                    f32::MAX
                ),
            });
        }
        if clipped {
            self.approx(
                "camera.distance",
                format!(
                    "a surface lies nearer the eye than {near:.3e}, where Mitsuba's sensor \
                     starts (near_clip, {CLIP_RATIO:e} of the farthest surface's distance)"
                ),
            );
        }
        // The eye in f32 is off by up to half a float's spacing: against a pixel's width
        // at the nearest surface, the image Mitsuba renders is shifted by that much. (A
        // surface through the eye has no such width; the near clip above says so.)
        let off = eye * f64::from(f32::EPSILON) / 2.0;
        let pixel = 2.0 * nearest * f.tan_half_vfov / f64::from(s.height);
        if pixel > 0.0 && off > EYE_SHIFT_PIXELS * pixel {
            self.approx(
                "camera.distance",
                format!(
                    "the eye, {eye:.3e} from the origin, is held to {off:.1e} in Mitsuba's \
                     32-bit floats: up to {:.2} of a pixel at the nearest surface",
                    off / pixel
                ),
            );
        }
        match s.pixel_filter {
            PixelFilter::Box if s.filter_width == 0.5 => {}
            other => self.approx(
                "render.pixel_filter",
                format!(
                    "{other:?} (filter_width {}) rendered with Mitsuba's box filter over the pixel",
                    s.filter_width
                ),
            ),
        }
        let _ = writeln!(
            self.xml,
            "  <sensor type=\"perspective\">\n    <string name=\"fov_axis\" value=\"y\"/>\n    \
         <float name=\"fov\" value=\"{}\"/>\n    <float name=\"near_clip\" value=\"{near}\"/>\n    \
         <float name=\"far_clip\" value=\"{far}\"/>\n    <transform name=\"to_world\">\n      \
         <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n    </transform>\n    \
         <sampler type=\"independent\">\n      <integer name=\"sample_count\" value=\"{}\"/>\n    \
         </sampler>\n    <film type=\"hdrfilm\">\n      <integer name=\"width\" value=\"{}\"/>\n      \
         <integer name=\"height\" value=\"{}\"/>\n      <string name=\"pixel_format\" value=\"rgb\"/>\n      \
         <rfilter type=\"box\"/>\n    </film>\n  </sensor>",
            scene.camera.vfov.to_degrees(),
            v3(f.eye),
            v3(f.eye + f.forward),
            v3(f.up),
            s.spp.max(1),
            s.width,
            s.height
        );

        if scene.ambient != DVec3::ZERO {
            self.approx(
                "render.ambient",
                "the ambient term (added to every pixel) is left out".into(),
            );
        }
        if !s.features.terms.is_empty() {
            self.approx(
                "features",
                "lighting terms (ambient occlusion, indirect light) are left out: Mitsuba \
             renders the direct light"
                    .into(),
            );
        }
        if !s.falloff {
            self.approx(
                "render.falloff",
                "falloff off: Mitsuba's lights always fall off as 1/d^2".into(),
            );
        }
        Ok(())
    }

    fn materials(&mut self) -> Result<(), ExportError> {
        let scene = &self.e.scene;
        for (i, m) in scene.materials.iter().enumerate() {
            if i == VOID as usize || !self.used[i] {
                continue;
            }
            let key = |k: &str| format!("materials[{}].{k}", m.name);
            if m.ks > 0.0 {
                self.approx(&key("ks"), "the Phong highlight is left out".into());
            }
            if m.emission != DVec3::ZERO {
                self.approx(
                    &key("emission"),
                    "emissive voxels are not exported (voxlab shows them; they light nothing)"
                        .into(),
                );
            }
            if m.kt > 0.0 {
                self.dielectric(m);
            }
            if m.kd > 0.0 && m.kr > 0.0 && m.kt == 0.0 && m.kd + m.kr > 1.0 {
                self.approx(
                    &key("kr"),
                    format!(
                        "kd + kr = {} > 1: the blend of diffuse and mirror is scaled to 1",
                        m.kd + m.kr
                    ),
                );
            }
            let _ = writeln!(self.xml, "{}", bsdf(i, m));
            if let Some(sigma) = self.interior(m) {
                // Mitsuba reads an RGB sigma_t in [0, 1] times `scale`, a 32-bit float.
                let scale = sigma.max_element().max(f64::MIN_POSITIVE);
                if scale > f32::MAX as f64 {
                    return Err(ExportError::OutOfRange {
                        file: self.file.clone(),
                        key: key("sigma"),
                        what: format!(
                            "an extinction of {scale:e} per unit is beyond Mitsuba's 32-bit floats"
                        ),
                    });
                }
                let _ = writeln!(
                    self.xml,
                    "  <medium type=\"homogeneous\" id=\"interior{i}\">\n    \
                 <rgb name=\"sigma_t\" value=\"{}\"/>\n    <float name=\"scale\" value=\"{scale}\"/>\n    \
                 <rgb name=\"albedo\" value=\"0, 0, 0\"/>\n  </medium>",
                    v3(sigma / scale)
                );
            }
        }
        Ok(())
    }

    /// The meshes, one per material: the voxels' faces merged, or the traced surface's
    /// triangles; each written as a PLY file.
    /// The grid's faces (greedy meshing), or the error that there would be too many.
    fn voxel_faces(&self) -> Result<Vec<MaterialTriangles>, ExportError> {
        let scene = &self.e.scene;
        Ok(
            greedy_faces(&scene.grid, &scene.materials, MAX_EXPORT_TRIANGLES)
                .ok_or_else(|| ExportError::TooLarge {
                    file: self.file.clone(),
                    what: format!(
                        "the voxels' faces need more than {MAX_EXPORT_TRIANGLES} triangles \
                     after merging"
                    ),
                })?
                .into_iter()
                .map(|(m, tris)| (m, tris, Vec::new()))
                .collect(),
        )
    }

    fn geometry(&mut self) -> Result<Vec<MaterialTriangles>, ExportError> {
        let (scene, s) = (&self.e.scene, &self.e.settings);
        let meshes: Vec<MaterialTriangles> = match s.surface.0.triangles {
            Some(triangles) => {
                let mesh = triangles(scene).map_err(|e| ExportError::Triangles {
                    file: self.file.clone(),
                    message: e.to_string(),
                })?;
                per_material(&mesh)
            }
            None if let Some((a, b)) = glass_contact(&scene.grid, &scene.materials) => {
                let (a, b) = (&scene.materials[a as usize], &scene.materials[b as usize]);
                self.approx(
                    &format!("materials[{}].ior", a.name),
                    format!(
                        "{} touches {}: their interface as {}'s dielectric against vacuum \
                         (voxlab refracts by the ratio of the two indices)",
                        a.name, b.name, a.name
                    ),
                );
                self.voxel_faces()?
            }
            None => self.voxel_faces()?,
        };
        for (m, tris, normals) in &meshes {
            let name = PathBuf::from("meshes").join(format!("material{m}.ply"));
            let medium = if self.interior(&scene.materials[*m as usize]).is_some() {
                format!("\n    <ref name=\"interior\" id=\"interior{m}\"/>")
            } else {
                String::new()
            };
            let _ = writeln!(
                self.xml,
                "  <shape type=\"ply\">\n    <string name=\"filename\" value=\"meshes/material{m}.ply\"/>\n    \
             <boolean name=\"face_normals\" value=\"{}\"/>\n    <ref id=\"material{m}\"/>{medium}\n  </shape>",
                normals.is_empty()
            );
            self.out.triangles += tris.len();
            self.out.files.push((name, ply(tris, normals)));
        }
        Ok(meshes)
    }

    /// Light `j`, with the surfaces' triangles (`quads`) to check its falloff clamp.
    fn light(&mut self, j: usize, light: &Light, quads: &[[DVec3; 3]]) -> Result<(), ExportError> {
        let s = &self.e.settings;
        let key = |k: &str| format!("lights[{j}].{k}");
        let c = light.color() * light.intensity() * std::f64::consts::PI;
        let reach = match light {
            Light::Point(_) => 0.0,
            Light::Area(a) => match a.shape {
                AreaShape::Rect { width, height } => 0.5 * width.hypot(height),
                AreaShape::Disk { radius } | AreaShape::Sphere { radius } => radius,
            },
        };
        if s.falloff && s.falloff_min_distance > 0.0 {
            let near = quads
                .iter()
                .map(|t| point_triangle_distance(light.position(), t))
                .fold(f64::INFINITY, f64::min);
            if near - reach < s.falloff_min_distance {
                self.approx(
                    "render.falloff_min_distance",
                    format!(
                        "light {j} comes within falloff_min_distance of a surface, where \
                     voxlab clamps 1/d^2 and Mitsuba does not"
                    ),
                );
            }
        }
        if let Some(glass) = self.transparent_around(light) {
            self.approx(
                &key("position"),
                format!(
                    "the light lies (in part) in {glass}'s voxels: voxlab's shadow rays \
                     that start in a transparent voxel stop there under opaque shadows (the \
                     start voxel counts), Mitsuba's reach a light inside the same glass"
                ),
            );
        }
        self.within_f32(j, c, "intensity (pi I color)")?;
        if let Light::Area(a) = light
            && let AreaShape::Rect { width, height } = a.shape
            && (width == 0.0) != (height == 0.0)
        {
            return Err(ExportError::OutOfRange {
                file: self.file.clone(),
                key: key("size"),
                what: format!(
                    "a rect of sides {} x {} is a line light, which Mitsuba has no emitter \
                     for (give both sides > 0, or both 0 for a point light)",
                    short_number(width),
                    short_number(height)
                ),
            });
        }
        let below_floats = if light.is_area() {
            self.below_mitsuba_floats(light, quads)
        } else {
            None
        };
        if let (Some(what), Light::Area(a)) = (&below_floats, light) {
            let size = match a.shape {
                AreaShape::Rect { .. } => "size",
                AreaShape::Disk { .. } | AreaShape::Sphere { .. } => "radius",
            };
            self.approx(&key(size), format!("{what}; written as a point light"));
        }
        // A point light, an area light of size 0, or one below what Mitsuba's floats
        // resolve, is Mitsuba's point light.
        if !light.is_area() || below_floats.is_some() {
            if let Light::Area(a) = light
                && a.emission == Emission::Lambertian
            {
                self.approx(
                    &key("emission"),
                    "a Lambertian light (a cosine spot) as a point light".into(),
                );
            }
            let _ = writeln!(
                self.xml,
                "  <emitter type=\"point\">\n    <point name=\"position\" value=\"{}\"/>\n    \
             <rgb name=\"intensity\" value=\"{}\"/>\n  </emitter>",
                v3(light.position()),
                v3(c)
            );
            return Ok(());
        }
        match light {
            Light::Point(_) => unreachable!("a point light is not an area light"),
            Light::Area(a) => self.area_light(j, a, c),
        }
    }

    /// Area light `j` as Mitsuba's shape of its kind with an `area` emitter; `c` is its
    /// `pi I color`.
    fn area_light(&mut self, j: usize, a: &AreaLight, c: DVec3) -> Result<(), ExportError> {
        let key = |k: &str| format!("lights[{j}].{k}");
        let (u, v, n) = a.frame();
        let (kind, area, su, sv) = match a.shape {
            AreaShape::Rect { width, height } => {
                ("rectangle", width * height, 0.5 * width, 0.5 * height)
            }
            AreaShape::Disk { radius } => (
                "disk",
                std::f64::consts::PI * radius * radius,
                radius,
                radius,
            ),
            AreaShape::Sphere { radius } => ("sphere", 0.0, radius, radius),
        };
        let radiance = match (a.shape, a.emission) {
            (AreaShape::Sphere { radius }, _) => {
                self.approx(
                    &key("type"),
                    "voxlab's sphere light emits isotropically from each point; \
                 Mitsuba's sphere is Lambertian (the same unoccluded light, a \
                 different penumbra)"
                        .into(),
                );
                // A Lambertian sphere of radiance L sends L pi R^2 in every
                // direction: as a point of intensity pi I (the 1/pi of Mitsuba's
                // diffuse BSDF undone), L = I / R^2.
                c / (std::f64::consts::PI * radius * radius)
            }
            (_, Emission::Lambertian) => c / area,
            (_, Emission::Isotropic) => {
                self.approx(
                    &key("emission"),
                    "isotropic emission as a Lambertian emitter of the power its \
                 front half sends (L = 2 I / A); nothing behind it"
                        .into(),
                );
                2.0 * c / area
            }
        };
        self.within_f32(j, radiance, "radiance")?;
        self.emitter_shapes.push(j);
        let transform = if kind == "sphere" {
            format!(
                "<point name=\"center\" value=\"{}\"/>\n    <float name=\"radius\" value=\"{}\"/>",
                v3(a.position),
                su
            )
        } else {
            // Columns: u, v scaled to the half extents, the normal, the centre.
            let (x, y) = (u * su, v * sv);
            format!(
                "<transform name=\"to_world\">\n      <matrix value=\"{} {} {} {} {} {} {} {} {} {} {} {} 0 0 0 1\"/>\n    </transform>",
                x.x,
                y.x,
                n.x,
                a.position.x,
                x.y,
                y.y,
                n.y,
                a.position.y,
                x.z,
                y.z,
                n.z,
                a.position.z
            )
        };
        let _ = writeln!(
            self.xml,
            "  <shape type=\"{kind}\">\n    {transform}\n    <bsdf type=\"diffuse\">\n      \
         <rgb name=\"reflectance\" value=\"0, 0, 0\"/>\n    </bsdf>\n    \
         <emitter type=\"area\">\n      <rgb name=\"radiance\" value=\"{}\"/>\n    \
         </emitter>\n  </shape>",
            v3(radiance)
        );
        Ok(())
    }

    /// The name of a transparent material (`kt > 0`, not void) among the voxels that light
    /// `light`'s bounding box (widened by a millionth of a voxel, so a light on a face
    /// counts both sides) overlaps.
    fn transparent_around(&self, light: &Light) -> Option<String> {
        let (scene, grid) = (&self.e.scene, &self.e.scene.grid);
        let points = emitter_shapes::outline(light);
        let pad = DVec3::splat(1e-6 * grid.voxel_size());
        let lo = points.iter().fold(DVec3::INFINITY, |a, &p| a.min(p)) - pad;
        let hi = points.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p)) + pad;
        let top = grid.dims().as_dvec3() - 1.0;
        let cell = |p: DVec3| {
            ((p - grid.world_min()) / grid.voxel_size())
                .floor()
                .clamp(DVec3::splat(-1.0), top + 1.0)
        };
        let (a, b) = (cell(lo).max(DVec3::ZERO), cell(hi).min(top));
        if a.cmpgt(b).any() {
            return None;
        }
        let (a, b) = (a.as_ivec3(), b.as_ivec3());
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    let id = grid.get(IVec3::new(x, y, z));
                    let m = &scene.materials[id as usize];
                    if id != VOID && m.kt > 0.0 {
                        return Some(m.name.clone());
                    }
                }
            }
        }
        None
    }

    /// The lights whose Mitsuba shape may stop another light's shadow rays, which pass
    /// through voxlab's lights: each an approximation (module `emitter_shapes`); `tris`
    /// are the scene's triangles.
    fn emitters_in_the_way(&mut self, tris: &[[DVec3; 3]]) {
        if self.emitter_shapes.is_empty() {
            return;
        }
        let scene = &self.e.scene;
        let surfaces = emitter_shapes::Bounds::of(tris.iter().flatten().copied());
        // A touch within the rounding of the coordinates involved counts as a meeting.
        let scale = tris
            .iter()
            .flatten()
            .copied()
            .chain(scene.lights.iter().flat_map(emitter_shapes::outline))
            .map(|p| p.abs().max_element())
            .fold(0.0, f64::max);
        let slack = 1e-9 * scale;
        for j in self.emitter_shapes.clone() {
            let others = emitter_shapes::in_the_way(j, &scene.lights, &surfaces, slack);
            if others.is_empty() {
                continue;
            }
            let list = others
                .iter()
                .map(|k| format!("lights[{k}]"))
                .collect::<Vec<_>>()
                .join(", ");
            self.approx(
                &format!("lights[{j}].position"),
                format!(
                    "Mitsuba's emitter is a shape, which may stop the shadow rays toward \
                     {list}; voxlab's lights are not surfaces, and shadow rays pass through \
                     them (as under voxlab.mitsuba.Whitted)"
                ),
            );
        }
    }

    /// Mitsuba reads 32-bit floats: a value of light `j` beyond them would be infinite
    /// there.
    fn within_f32(&self, j: usize, v: DVec3, what: &str) -> Result<(), ExportError> {
        if v.max_element() > f32::MAX as f64 {
            return Err(ExportError::OutOfRange {
                file: self.file.clone(),
                key: format!("lights[{j}].intensity"),
                what: format!(
                    "the exported {what} {} is beyond Mitsuba's 32-bit floats (at most {:e})",
                    v.max_element(),
                    f32::MAX
                ),
            });
        }
        Ok(())
    }

    /// Why Mitsuba's 32-bit floats cannot hold area light `light` faithfully, if they
    /// cannot; `quads` are the scene's triangles, which it lights. Measured on Mitsuba
    /// 3.9.1 (docs/mitsuba.md, "Lights below Mitsuba's floats"): a rectangle turns into
    /// a mesh in world space, whose corners merge once its sides near the spacing of
    /// floats at its position (a side of 1e-6 at 18 from the origin fails to load), and a
    /// disk fades from 3e-9; a sphere is sampled by the cone it subtends, whose
    /// `1 - cos` is lost in f32 once `R / d` falls toward 1e-3 (10 % too bright at
    /// `R / d = 7e-4`, black below), for `d` up to the farthest surface.
    fn below_mitsuba_floats(&self, light: &Light, quads: &[[DVec3; 3]]) -> Option<String> {
        let Light::Area(a) = light else {
            return None;
        };
        let p = a.position;
        let farthest = quads
            .iter()
            .flatten()
            .map(|v| v.distance(p))
            .fold(0.0, f64::max);
        match a.shape {
            AreaShape::Rect { width, height } => {
                let floor = LIGHT_SPACING_FLOOR * p.abs().max_element().max(farthest);
                (0.5 * width.min(height) < floor).then(|| {
                    format!(
                        "a rect of sides {} x {}: a half side below {floor:.3e} \
                         (2^-17 of its distance from the origin or its farthest surface) \
                         is lost in Mitsuba's 32-bit floats",
                        short_number(width),
                        short_number(height)
                    )
                })
            }
            AreaShape::Disk { radius } => {
                let floor = LIGHT_SPACING_FLOOR * p.abs().max_element().max(farthest);
                (radius < floor).then(|| {
                    format!(
                        "a disk of radius {}: below {floor:.3e} (2^-17 of its distance \
                         from the origin or its farthest surface) it is lost in Mitsuba's \
                         32-bit floats",
                        short_number(radius)
                    )
                })
            }
            AreaShape::Sphere { radius } => {
                let floor = SPHERE_CONE_FLOOR * farthest;
                (radius < floor).then(|| {
                    format!(
                        "a sphere of radius {}: below {floor:.3e} (2^-8 of the distance \
                         to its farthest surface) Mitsuba's sampling of the cone it subtends \
                         loses its 1 - cos in 32-bit floats",
                        short_number(radius)
                    )
                })
            }
        }
    }
}

/// A rect's half side or a disk's radius, as a share of the light's distance from the
/// origin or its farthest surface, below which Mitsuba's f32 loses the shape: 2^-17,
/// 64 floats' spacing (`Writer::below_mitsuba_floats`).
const LIGHT_SPACING_FLOOR: f64 = 1.0 / (1u64 << 17) as f64;

/// A sphere light's radius, as a share of the distance to its farthest surface, below
/// which Mitsuba's cone sampling loses `1 - cos` (about 1e-5 there: under 1 % of it in
/// f32 rounding).
const SPHERE_CONE_FLOOR: f64 = 1.0 / 256.0;

fn v3(v: DVec3) -> String {
    format!("{}, {}, {}", v.x, v.y, v.z)
}

/// Text for an XML comment or attribute.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace("--", "- -")
}

/// Two different transparent materials (`kt > 0`) in face-adjacent voxels, if any:
/// their shared face is one dielectric in the export, against vacuum.
fn glass_contact(grid: &Grid, materials: &[Material]) -> Option<(u8, u8)> {
    let clear = |m: u8| m != VOID && materials[m as usize].kt > 0.0;
    let d = grid.dims().as_ivec3();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let p = IVec3::new(x, y, z);
                let a = grid.get(p);
                if !clear(a) {
                    continue;
                }
                for step in [IVec3::X, IVec3::Y, IVec3::Z] {
                    let q = p + step;
                    if q.cmplt(d).all() {
                        let b = grid.get(q);
                        if b != a && clear(b) {
                            return Some((a.min(b), a.max(b)));
                        }
                    }
                }
            }
        }
    }
    None
}

/// Which palette entries some voxel uses.
fn used_materials(grid: &Grid) -> [bool; 256] {
    let mut used = [false; 256];
    let d = grid.dims().as_ivec3();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                used[grid.get(IVec3::new(x, y, z)) as usize] = true;
            }
        }
    }
    used
}

/// The Mitsuba BSDF of material `i` (id `material{i}`), by the module's mapping.
fn bsdf(i: usize, m: &Material) -> String {
    let rgb = |v: DVec3| format!("<rgb name=\"reflectance\" value=\"{}\"/>", v3(v));
    let id = format!("material{i}");
    if m.kt > 0.0 {
        let dielectric = |id: &str, scale: f64| {
            format!(
                "<bsdf type=\"dielectric\"{id}>\n    <float name=\"int_ior\" value=\"{}\"/>\n    \
                 <float name=\"ext_ior\" value=\"1\"/>\n    \
                 <spectrum name=\"specular_reflectance\" value=\"{}\"/>\n    \
                 <spectrum name=\"specular_transmittance\" value=\"{}\"/>\n  </bsdf>",
                // Mitsuba refuses equal indices (an approximation: Writer::dielectric).
                if m.ior == 1.0 { 1.0 + 1e-6 } else { m.ior },
                m.kr * scale,
                m.kt * scale
            )
        };
        if m.kd <= 0.0 {
            return format!("  {}", dielectric(&format!(" id=\"{id}\""), 1.0));
        }
        // (1 - w) rho + w D(kr / w, kt / w) = kd albedo + D(kr, kt) with w = max(kr, kt)
        // and rho = kd albedo / (1 - w); past 1, rho is scaled to 1 (an approximation).
        let w = diffuse_dielectric_blend(m).unwrap_or_else(|| m.kr.max(m.kt).min(0.5));
        let rho = (m.albedo * m.kd / (1.0 - w)).min(DVec3::ONE);
        return format!(
            "  <bsdf type=\"blendbsdf\" id=\"{id}\">\n    <float name=\"weight\" value=\"{w}\"/>\n    \
             <bsdf type=\"diffuse\">\n      {}\n    </bsdf>\n    {}\n  </bsdf>",
            rgb(rho),
            dielectric("", 1.0 / w)
        );
    }
    let diffuse = m.albedo * m.kd;
    if m.kr <= 0.0 {
        return format!(
            "  <bsdf type=\"twosided\" id=\"{id}\">\n    <bsdf type=\"diffuse\">\n      {}\n    </bsdf>\n  </bsdf>",
            rgb(diffuse)
        );
    }
    let mirror = |kr: f64| {
        format!(
            "<bsdf type=\"conductor\">\n      <string name=\"material\" value=\"none\"/>\n      \
             <spectrum name=\"specular_reflectance\" value=\"{kr}\"/>\n    </bsdf>"
        )
    };
    if m.kd <= 0.0 {
        return format!(
            "  <bsdf type=\"twosided\" id=\"{id}\">\n    {}\n  </bsdf>",
            mirror(m.kr.min(1.0))
        );
    }
    // (1 - w) rho_d + w rho_m = kd albedo + kr with w = kr / s, rho_d = s albedo and
    // rho_m = s, s = kd + kr (at most 1: a larger s is scaled to 1, an approximation).
    let s = m.kd + m.kr;
    let w = m.kr / s;
    format!(
        "  <bsdf type=\"twosided\" id=\"{id}\">\n    <bsdf type=\"blendbsdf\">\n      \
         <float name=\"weight\" value=\"{w}\"/>\n      <bsdf type=\"diffuse\">\n        {}\n      </bsdf>\n      {}\n    </bsdf>\n  </bsdf>",
        rgb(m.albedo * s.min(1.0)),
        mirror(s.min(1.0))
    )
}

/// The blend weight `w = max(kr, kt)` of the dielectric when a transparent material
/// with a diffuse term maps exactly onto Mitsuba's `blendbsdf` of `diffuse` and
/// `dielectric` (the diffuse reflectance `kd albedo / (1 - w)` at most 1).
fn diffuse_dielectric_blend(m: &Material) -> Option<f64> {
    let w = m.kr.max(m.kt);
    (w > 0.0 && w < 1.0 && m.kd * m.albedo.max_element() <= 1.0 - w).then_some(w)
}

/// The triangles of a traced mesh, with their shading normals, per material.
type MaterialTriangles = (u8, Vec<[DVec3; 3]>, Vec<[DVec3; 3]>);

fn per_material(mesh: &SurfaceMesh) -> Vec<MaterialTriangles> {
    mesh.materials()
        .into_iter()
        .map(|m| {
            let (mut tris, mut normals) = (Vec::new(), Vec::new());
            for (t, _) in mesh
                .triangles
                .iter()
                .zip(&mesh.triangle_material)
                .filter(|(_, k)| **k == m)
            {
                tris.push(t.map(|i| mesh.positions[i as usize]));
                normals.push(t.map(|i| mesh.normals[i as usize]));
            }
            (m, tris, normals)
        })
        .collect()
}

/// Whether the face of voxel material `a` toward its neighbour `b` is a surface of
/// `a`: `a` is not void, differs from `b`, and is seen from `b` (void, or glass in
/// front of an opaque material); between two different glasses the lower index owns
/// the face.
fn owns_face(a: u8, b: u8, materials: &[Material]) -> bool {
    if a == VOID || a == b {
        return false;
    }
    if b == VOID {
        return true;
    }
    let clear = |m: u8| materials[m as usize].kt > 0.0;
    match (clear(a), clear(b)) {
        (false, false) => false,
        (false, true) => true,
        (true, false) => false,
        (true, true) => a < b,
    }
}

/// The faces of the grid's voxels between different media, merged per material and
/// direction into maximal rectangles (greedy meshing), two triangles each, in world
/// coordinates, wound counter-clockwise seen from the side the face is seen from.
/// `None` once more than `max_triangles` would be needed.
pub fn greedy_faces(
    grid: &Grid,
    materials: &[Material],
    max_triangles: usize,
) -> Option<Vec<(u8, Vec<[DVec3; 3]>)>> {
    let mut count = 0usize;
    let dims = grid.dims().as_ivec3();
    let (origin, vs) = (grid.origin(), grid.voxel_size());
    let mut per: Vec<Vec<[DVec3; 3]>> = vec![Vec::new(); 256];
    for d in 0..3 {
        let (u, v) = ((d + 1) % 3, (d + 2) % 3);
        let (nu, nv) = (dims[u] as usize, dims[v] as usize);
        let mut mask = vec![0u16; nu * nv];
        for sign in [-1i32, 1] {
            for x in 0..dims[d] {
                for j in 0..nv {
                    for i in 0..nu {
                        let mut a = IVec3::ZERO;
                        a[d] = x;
                        a[u] = i as i32;
                        a[v] = j as i32;
                        let mut b = a;
                        b[d] += sign;
                        let (ma, mb) = (grid.get(a), grid.get(b));
                        mask[j * nu + i] = if owns_face(ma, mb, materials) {
                            ma as u16 + 1
                        } else {
                            0
                        };
                    }
                }
                let plane = (x + i32::from(sign > 0)) as f64;
                for j in 0..nv {
                    let mut i = 0;
                    while i < nu {
                        let m = mask[j * nu + i];
                        if m == 0 {
                            i += 1;
                            continue;
                        }
                        let mut w = 1;
                        while i + w < nu && mask[j * nu + i + w] == m {
                            w += 1;
                        }
                        let mut h = 1;
                        'grow: while j + h < nv {
                            for k in 0..w {
                                if mask[(j + h) * nu + i + k] != m {
                                    break 'grow;
                                }
                            }
                            h += 1;
                        }
                        for jj in 0..h {
                            for k in 0..w {
                                mask[(j + jj) * nu + i + k] = 0;
                            }
                        }
                        let corner = |cu: usize, cv: usize| {
                            let mut p = DVec3::ZERO;
                            p[d] = plane;
                            p[u] = cu as f64;
                            p[v] = cv as f64;
                            origin + vs * p
                        };
                        let q = [
                            corner(i, j),
                            corner(i + w, j),
                            corner(i + w, j + h),
                            corner(i, j + h),
                        ];
                        // e_u x e_v = e_d: this order faces +d.
                        let tris = if sign > 0 {
                            [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                        } else {
                            [[q[0], q[2], q[1]], [q[0], q[3], q[2]]]
                        };
                        count += 2;
                        if count > max_triangles {
                            return None;
                        }
                        per[(m - 1) as usize].extend_from_slice(&tris);
                        i += w;
                    }
                }
            }
        }
    }
    Some(
        per.into_iter()
            .enumerate()
            .filter(|(_, t)| !t.is_empty())
            .map(|(m, t)| (m as u8, t))
            .collect(),
    )
}

/// Binary little-endian PLY of triangles (three vertices each), with vertex normals
/// when given.
fn ply(tris: &[[DVec3; 3]], normals: &[[DVec3; 3]]) -> Vec<u8> {
    let with_normals = !normals.is_empty();
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment voxlab export\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n",
        3 * tris.len()
    );
    if with_normals {
        header += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    header += &format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        tris.len()
    );
    let mut out = header.into_bytes();
    for (k, t) in tris.iter().enumerate() {
        for (c, p) in t.iter().enumerate() {
            for x in p.to_array() {
                out.extend_from_slice(&(x as f32).to_le_bytes());
            }
            if with_normals {
                for x in normals[k][c].to_array() {
                    out.extend_from_slice(&(x as f32).to_le_bytes());
                }
            }
        }
    }
    for k in 0..tris.len() as i32 {
        out.push(3);
        for i in 0..3 {
            out.extend_from_slice(&(3 * k + i).to_le_bytes());
        }
    }
    out
}

/// The shift of Mitsuba's image, in pixels at the camera's target, from its eye's
/// rounding to f32, above which the export is approximated.
const EYE_SHIFT_PIXELS: f64 = 0.01;

/// The nearest surface's distance over the farthest's below which Mitsuba's sensor
/// stops seeing (its own defaults, 0.01 and 1e4, are this ratio).
const CLIP_RATIO: f64 = 1e-6;

/// Mitsuba's sensor clips its rays to `[near_clip, far_clip]`, by default 0.01 to 1e4
/// world units, where voxlab's camera rays have no bounds: a scene farther than 1e4 from
/// the eye (a camera 1e5 out with a narrow field of view, a grid of `voxel_size = 1e3`)
/// rendered black there, and one nearer than 0.01 lost its near surfaces. The range
/// here holds every triangle of `tris` seen from `eye`: far past the farthest vertex
/// (by 1 %, for f32 rounding), near at half the nearest surface, but no nearer than
/// [`CLIP_RATIO`] of far. Returns near, far and the nearest surface's distance (infinite
/// without surfaces).
fn clip_range(eye: DVec3, tris: &[[DVec3; 3]]) -> (f64, f64, f64) {
    if tris.is_empty() {
        return (1e-2, 1e4, f64::INFINITY);
    }
    let farthest = tris
        .iter()
        .flatten()
        .map(|v| v.distance(eye))
        .fold(0.0, f64::max);
    let nearest = tris
        .iter()
        .map(|t| point_triangle_distance(eye, t))
        .fold(f64::INFINITY, f64::min);
    let far = 1.01 * farthest;
    let floor = CLIP_RATIO * far;
    (f64::max(0.5 * nearest, floor), far, nearest)
}

/// Distance from `p` to the triangle `t` (Ericson, "Real-Time Collision Detection",
/// 5.1.5, by the closest point).
fn point_triangle_distance(p: DVec3, t: &[DVec3; 3]) -> f64 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + d1 / (d1 - d3) * ab)).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + d2 / (d2 - d6) * ac)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length()
}

/// Writes [`mitsuba`]'s scene into `dir` (created when missing): `scene.xml`, its
/// meshes under `meshes/`, and `scene.xml.json`, the record of what made them (the
/// experiment's text and inputs hashed, the build, the approximations). All or nothing:
/// every file is filled under a temporary name and renamed only when all are complete.
/// Refused before anything is written: `dir` an existing file, or any output that is
/// one of the experiment's own inputs. `text` is the experiment's text as parsed (with
/// its overrides), for the record and for the inputs it names.
pub fn write_mitsuba(
    e: &Experiment,
    text: &str,
    dir: &std::path::Path,
    strict: bool,
) -> crate::Result<MitsubaScene> {
    use crate::error::{Error, ErrorKind};
    // The directory is the command line's positional DIR and Python's `dir`: named alone.
    crate::output::check_directory_output(
        "",
        dir,
        "export writes a directory (scene.xml and meshes/)",
    )
    .map_err(|m| Error::new(ErrorKind::Output, m))?;
    let scene = mitsuba(e, strict)?;
    let xml = dir.join("scene.xml");
    let mut outputs: Vec<PathBuf> = scene.files.iter().map(|(p, _)| dir.join(p)).collect();
    outputs.push(crate::output::sidecar_path(&xml));
    let inputs = crate::experiment::write::experiment_inputs(e, text);
    if let Some((o, i)) = crate::experiment::write::overwrites(&outputs, &inputs) {
        return Err(Error::new(
            ErrorKind::Output,
            format!(
                "{}: export would write {}, which is the experiment's input {}; export never \
                 overwrites its input",
                dir.display(),
                o.display(),
                i.display()
            ),
        ));
    }
    let input_refs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    let record = crate::output::record(
        "voxlab export --to mitsuba",
        &input_refs,
        serde_json::json!({
            "experiment": e.name,
            "experiment_text": text,
            // The voxels exported, whatever gave them (the text's [scene], or an array
            // set in memory, which the text does not give).
            "grid": e.scene.grid.record(),
            "strict": strict,
            "triangles": scene.triangles,
            "files": scene.files.iter().map(|(p, _)| p.display().to_string()).collect::<Vec<_>>(),
            "approximations": scene.approximations.iter()
                .map(|a| serde_json::json!({"key": a.key, "mapping": a.mapping}))
                .collect::<Vec<_>>(),
            // The Whitted tree's limits, which `voxlab.mitsuba.Whitted` (python) follows.
            "whitted": {
                "max_reflection_depth": e.settings.max_reflection_depth,
                "max_refraction_depth": e.settings.max_refraction_depth,
                "max_depth": e.settings.max_depth,
                "seed_rules": e.settings.rules == crate::render::Rules::Seed,
                // Under the seed's rules a ray that leaves the grid is a miss, also from
                // inside glass on its boundary, where Mitsuba splits it.
                "grid_bounds": [
                    e.scene.grid.world_min().to_array(),
                    e.scene.grid.world_max().to_array(),
                ],
            },
        }),
    );
    let record_text = serde_json::to_string_pretty(&record).expect("a JSON value serialises");
    let record_path = crate::output::sidecar_path(&xml);
    let mut fills: Vec<(PathBuf, crate::output::Fill<'_>)> = scene
        .files
        .iter()
        .map(|(p, bytes)| {
            let path = dir.join(p);
            let fill = crate::output::bytes_fill(&path, bytes);
            (path, fill)
        })
        .collect();
    fills.push((
        record_path.clone(),
        crate::output::bytes_fill(&record_path, record_text.as_bytes()),
    ));
    crate::output::write_together(fills)?;
    Ok(scene)
}
