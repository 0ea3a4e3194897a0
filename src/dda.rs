//! Ray/box entry and Amanatides-Woo voxel traversal in f64 world coordinates.
//!
//! J. Amanatides and A. Woo, "A fast voxel traversal algorithm for ray tracing",
//! Eurographics 1987. The rules (entry voxel, tie-breaking, limits) are those of
//! `src/trace_contract.md`, which the WGSL kernel implements too.

use glam::{DVec3, IVec3};

use crate::scene::Grid;
use crate::sparse::{Region, Regions};
use crate::triangles::{SURFACE_TAG, SurfaceTrace, WatertightRay};

/// One voxel on a ray's path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visit {
    pub voxel: IVec3,
    /// Distance along the ray at which the ray enters this voxel (0 for the start voxel
    /// of a ray that starts inside the grid).
    pub t_enter: f64,
    /// Outward normal of the face the ray entered through; zero for a start voxel.
    pub normal: DVec3,
    /// The voxel's material.
    pub material: u8,
}

/// The voxels a ray visits, in order, until it leaves the grid or reaches `t_limit`.
/// `steps` counts moves from one voxel to the next (the "voxel steps" of the benchmarks).
pub struct Dda<'a> {
    grid: &'a Grid,
    /// The traversal's regions: [`Dda::skip_region`] leaves one at once.
    regions: Option<&'a dyn Regions>,
    /// The uniform region of the voxel last visited (that voxel alone without regions).
    region: Region,
    origin: DVec3,
    dir: DVec3,
    voxel: IVec3,
    step: IVec3,
    t_max: DVec3,
    t_limit: f64,
    pending: Option<Visit>,
    done: bool,
    pub steps: u64,
    /// Uniform regions left at once by [`Dda::skip_region`].
    pub skips: u64,
    /// A ray visits at most nx + ny + nz voxels: the bound ends any walk that float
    /// error (or a non-finite input) could stall, as the kernel's max_steps does.
    max_steps: u64,
    /// Where the last visited voxel ends along the ray once the traversal is over: the
    /// grid's exit or `t_limit`, whichever comes first.
    pub t_end: f64,
    /// Set when the traversal ended by leaving the grid: the voxel outside it that the
    /// last step reached and the normal of the face it left through (facing against
    /// the ray). `None` while it goes on, or when it ended at `t_limit` or never entered.
    pub exit: Option<(IVec3, DVec3)>,
}

/// Index of the smallest component, ties to the lowest axis.
fn argmin(v: DVec3) -> usize {
    if v.x <= v.y && v.x <= v.z {
        0
    } else if v.y <= v.z {
        1
    } else {
        2
    }
}

/// Index of the largest component, ties to the lowest axis.
fn argmax(v: DVec3) -> usize {
    if v.x >= v.y && v.x >= v.z {
        0
    } else if v.y >= v.z {
        1
    } else {
        2
    }
}

fn axis(a: usize) -> DVec3 {
    let mut e = DVec3::ZERO;
    e[a] = 1.0;
    e
}

impl<'a> Dda<'a> {
    /// Starts a traversal of `grid` by the ray `origin + t dir` (`dir` need not be unit;
    /// distances are in units of `|dir|`), visiting voxels entered at `t < t_limit`.
    pub fn new(grid: &'a Grid, origin: DVec3, dir: DVec3, t_limit: f64) -> Self {
        Self::over(grid, None, origin, dir, t_limit)
    }

    /// [`Dda::new`] over `grid` as a traversal's `regions` hold it (the same voxels), so
    /// that [`Dda::skip_region`] can leave a uniform region at once. Without regions it
    /// is `new`.
    pub fn over(
        grid: &'a Grid,
        regions: Option<&'a dyn Regions>,
        origin: DVec3,
        dir: DVec3,
        t_limit: f64,
    ) -> Self {
        let mut dda = Self {
            grid,
            regions,
            region: Region {
                material: crate::scene::VOID,
                lo: IVec3::ZERO,
                hi: IVec3::ONE,
            },
            origin,
            dir,
            voxel: IVec3::ZERO,
            step: IVec3::ZERO,
            t_max: DVec3::INFINITY,
            t_limit,
            pending: None,
            done: true,
            steps: 0,
            skips: 0,
            max_steps: {
                let d = grid.dims();
                d.x as u64 + d.y as u64 + d.z as u64 + 3
            },
            t_end: 0.0,
            exit: None,
        };
        let lo = grid.world_min();
        let hi = grid.world_max();
        let dims = grid.dims().as_ivec3();
        let local = grid.to_local(origin);
        let inside = (0..3).all(|a| local[a] >= 0.0 && local[a] < dims[a] as f64);

        let (voxel, t_start, normal) = if inside {
            (local.floor().as_ivec3().min(dims - 1), 0.0, DVec3::ZERO)
        } else {
            // Slabs; an axis the ray does not move along is all or nothing, so no 0 * inf.
            let mut near = DVec3::NEG_INFINITY;
            let mut far = DVec3::INFINITY;
            for a in 0..3 {
                if dir[a] == 0.0 {
                    if origin[a] < lo[a] || origin[a] > hi[a] {
                        return dda;
                    }
                } else {
                    let t1 = (lo[a] - origin[a]) / dir[a];
                    let t2 = (hi[a] - origin[a]) / dir[a];
                    near[a] = t1.min(t2);
                    far[a] = t1.max(t2);
                }
            }
            let t_enter = near.max_element().max(0.0);
            let t_exit = far.min_element();
            if t_enter > t_exit {
                return dda;
            }
            let a = argmax(near);
            let p = grid.to_local(origin + t_enter * dir);
            let v = p.floor().as_ivec3().clamp(IVec3::ZERO, dims - 1);
            let n = -dir[a].signum() * axis(a);
            (v, t_enter, n)
        };
        if t_start >= t_limit {
            return dda;
        }

        for a in 0..3 {
            if dir[a] > 0.0 {
                dda.step[a] = 1;
            } else if dir[a] < 0.0 {
                dda.step[a] = -1;
            }
            if dda.step[a] != 0 {
                dda.t_max[a] = dda.plane_t(a, dda.next_plane(a, voxel[a]));
            }
        }
        dda.voxel = voxel;
        let material = dda.look_up(voxel);
        dda.pending = Some(Visit {
            voxel,
            t_enter: t_start,
            normal,
            material,
        });
        dda.done = false;
        dda
    }
}

impl Dda<'_> {
    /// Where the voxel last visited ends along the ray (its exit plane, or `t_limit`).
    pub fn t_exit(&self) -> f64 {
        self.t_max.min_element().min(self.t_limit)
    }

    /// The ray parameter at which it crosses boundary plane `b` (voxel units) of axis
    /// `a`: `(plane - o) / d`, the one formula every `t_max` comes from, so a region's
    /// exit compares exactly as the dense walk's steps do (trace contract, "cast", 3).
    fn plane_t(&self, a: usize, b: i32) -> f64 {
        let plane = self.grid.world_min()[a] + self.grid.voxel_size() * b as f64;
        (plane - self.origin[a]) / self.dir[a]
    }

    /// The boundary plane a walk crosses when it leaves voxel index `c` along axis `a`.
    fn next_plane(&self, a: usize, c: i32) -> i32 {
        if self.step[a] > 0 { c + 1 } else { c }
    }

    /// The material of `v` (inside the grid), and its region for [`Dda::skip_region`].
    fn look_up(&mut self, v: IVec3) -> u8 {
        self.region = match self.regions {
            Some(r) => r.region(v, self.step),
            None => Region {
                material: self.grid.get(v),
                lo: v,
                hi: v + IVec3::ONE,
            },
        };
        self.region.material
    }

    /// Moves the walk to the last voxel of the uniform region of the voxel last visited
    /// through which the ray leaves it, as if it had visited every voxel between: the
    /// next visit is the first voxel past the region, with the distance and face the
    /// dense walk gives it. The dense walk leaves a box at its earliest exit plane `(t*,
    /// a*)`, ties to the lowest axis; every plane of another axis that comes before it
    /// in that order has been crossed by then. A no-op without regions or in a region of
    /// one voxel.
    pub fn skip_region(&mut self) {
        if self.done || self.region.is_voxel() {
            return;
        }
        let (lo, hi) = (self.region.lo, self.region.hi);
        let mut exit = (f64::INFINITY, 3);
        for a in 0..3 {
            if self.step[a] != 0 {
                let edge = if self.step[a] > 0 { hi[a] } else { lo[a] };
                let t = self.plane_t(a, edge);
                if t < exit.0 {
                    exit = (t, a);
                }
            }
        }
        let (t_star, a_star) = exit;
        if a_star == 3 || !t_star.is_finite() {
            return;
        }
        let before = |t: f64, b: usize| t < t_star || (t == t_star && b < a_star);
        let local = self.grid.to_local(self.origin + t_star * self.dir);
        for b in 0..3 {
            let s = self.step[b];
            if s == 0 {
                continue;
            }
            let last = if s > 0 { hi[b] - 1 } else { lo[b] };
            let (near, far) = (self.voxel[b].min(last), self.voxel[b].max(last));
            let mut c = (local[b].floor() as i32).clamp(near, far);
            while c != last && before(self.plane_t(b, self.next_plane(b, c)), b) {
                c += s;
            }
            while c != self.voxel[b] && !before(self.plane_t(b, self.next_plane(b, c - s)), b) {
                c -= s;
            }
            self.voxel[b] = c;
            self.t_max[b] = self.plane_t(b, self.next_plane(b, c));
        }
        self.skips += 1;
    }
}

impl Iterator for Dda<'_> {
    type Item = Visit;

    fn next(&mut self) -> Option<Visit> {
        if let Some(v) = self.pending.take() {
            return Some(v);
        }
        if self.done {
            return None;
        }
        let a = argmin(self.t_max);
        let t = self.t_max[a];
        if t >= self.t_limit || t.is_nan() || self.steps >= self.max_steps {
            self.done = true;
            self.t_end = self.t_limit;
            return None;
        }
        self.voxel[a] += self.step[a];
        self.t_max[a] = self.plane_t(a, self.next_plane(a, self.voxel[a]));
        self.steps += 1;
        if !self.grid.contains(self.voxel) {
            self.done = true;
            self.t_end = t;
            self.exit = Some((self.voxel, -(self.step[a] as f64) * axis(a)));
            return None;
        }
        let material = self.look_up(self.voxel);
        Some(Visit {
            voxel: self.voxel,
            t_enter: t,
            normal: -(self.step[a] as f64) * axis(a),
            material,
        })
    }
}

/// The first voxel on the ray whose material differs from `medium`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub voxel: IVec3,
    pub t: f64,
    /// The shading normal, facing the ray's side.
    pub normal: DVec3,
    /// The surface's own normal, facing the ray's side: secondary and shadow rays start
    /// off the surface along it. The face's normal on a voxel, where both are one.
    pub geometric: DVec3,
    /// The material past the surface (void when the ray leaves into void).
    pub material: u8,
}

/// Casts a ray travelling in `medium` under voxlab's model: the start voxel of a ray that
/// starts inside the grid is never a hit, and outside the grid is void, so a ray that
/// leaves a non-void medium through the grid's boundary hits void at the exit face
/// (`voxel` is then the first voxel outside the grid). Returns the hit (if any) and the
/// voxel steps taken.
pub fn cast(grid: &Grid, origin: DVec3, dir: DVec3, medium: u8) -> (Option<Hit>, u64) {
    cast_with(grid, origin, dir, medium, true)
}

/// [`cast`] with the boundary rule chosen: `exit_hits` false is the seed's, where
/// leaving the grid is always a miss.
pub fn cast_with(
    grid: &Grid,
    origin: DVec3,
    dir: DVec3,
    medium: u8,
    exit_hits: bool,
) -> (Option<Hit>, u64) {
    cast_over(grid, None, origin, dir, medium, exit_hits)
}

/// [`cast_with`] over `grid` as `regions` hold it: regions of the ray's medium are left
/// whole (the same hit; the steps count the moves made).
pub fn cast_over(
    grid: &Grid,
    regions: Option<&dyn Regions>,
    origin: DVec3,
    dir: DVec3,
    medium: u8,
    exit_hits: bool,
) -> (Option<Hit>, u64) {
    cast_through(grid, regions, None, origin, dir, medium, exit_hits, &mut 0)
}

/// [`cast_over`] with triangle surfaces (`crate::triangles`): `grid` is then their
/// tagged grid, a cell's triangles are tested inside its ray interval, and `tests`
/// counts the ray/triangle tests.
#[allow(clippy::too_many_arguments)]
pub fn cast_through(
    grid: &Grid,
    regions: Option<&dyn Regions>,
    surfaces: Option<&SurfaceTrace>,
    origin: DVec3,
    dir: DVec3,
    medium: u8,
    exit_hits: bool,
    tests: &mut u64,
) -> (Option<Hit>, u64) {
    let mut dda = Dda::over(grid, regions, origin, dir, f64::INFINITY);
    let ray = surfaces.map(|_| WatertightRay::new(origin, dir));
    let mut hit = None;
    while let Some(v) = dda.next() {
        if let (Some(s), Some(ray)) = (surfaces, ray.as_ref())
            && v.material == SURFACE_TAG
        {
            let window = (v.t_enter, dda.t_exit());
            if let Some(tr) = s.next_transition(v.voxel, ray, window, 0.0, medium, tests) {
                hit = Some(s.hit(v.voxel, dir, &tr));
                break;
            }
            continue;
        }
        // The start voxel is never a hit: the ray is in its medium by definition.
        if v.material != medium && v.normal != DVec3::ZERO {
            hit = Some(Hit {
                voxel: v.voxel,
                t: v.t_enter,
                normal: v.normal,
                geometric: v.normal,
                material: v.material,
            });
            break;
        }
        if v.material == medium {
            dda.skip_region();
        }
    }
    if hit.is_none()
        && exit_hits
        && medium != crate::scene::VOID
        && let Some((voxel, normal)) = dda.exit
    {
        hit = Some(Hit {
            voxel,
            t: dda.t_end,
            normal,
            geometric: normal,
            material: crate::scene::VOID,
        });
    }
    (hit, dda.steps)
}
