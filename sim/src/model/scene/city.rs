//! The generated `city:N` scene family: a deterministic city of exactly `N` triangles, for
//! workloads whose BVH is far larger than the caches (tens to hundreds of MB) without the shared
//! scene folder.
//!
//! The city is a `G x G` grid of 84 m blocks separated by 16 m streets on a ground plane
//! (asphalt streets, a grass margin). Each block is a raised sidewalk slab split into lots; each
//! lot holds a building (taller towards the centre, some with a set-back upper tier, some glass
//! towers) whose four facades carry a grid of recessed windows: every window is a hole in the
//! wall, four reveal quads and a glass pane, all real triangles, so the triangle count scales
//! with the window count. Roofs have a parapet, rooftop units, water tanks and antennas; streets
//! have lamp posts, lane dashes, crosswalks and manhole covers. Budgets from 10,000 triangles
//! get the street furniture and rooftop units; smaller ones only the buildings.
//!
//! Sizing: `G` grows with `sqrt(N)` so windows stay about 3 m apart; the window pitch is then
//! found by bisection so the facades use as much of the budget as possible, a few walls get one
//! more window column or row, and manhole covers (2 triangles) and at most one pennant triangle
//! make up the rest, so the scene has exactly `N` triangles. Every random choice comes from a
//! SplitMix64 generator seeded with [`CITY_SEED`], so a budget always gives the same scene.

use glam::Vec3;

use super::{Camera, Scene, SceneError};
use crate::model::splitmix::SplitMix64 as Rng;

mod geometry;

use geometry::{
    materials, BoxItem, Mesh, Rect, Roof, Tank, Wall, ASPHALT, CONCRETE, DARK, FLAG, GRASS, METAL,
    PAINT_WHITE, PARAPET, PARAPET_T, WALL0, WALL_COLOURS,
};

/// Triangle budget of the bare spec `city`.
pub const DEFAULT_TRIANGLES: u32 = 1_000_000;
/// Smallest accepted triangle budget.
pub const MIN_TRIANGLES: u32 = 1_000;
/// Largest accepted triangle budget (64M). BVHs of more than about 4.9M triangles do not fit the
/// 32-bit BVH address space with the default 8 KB treelets; the BVH build reports that.
pub const MAX_TRIANGLES: u32 = 64_000_000;
/// Seed of the generator's random numbers.
pub const CITY_SEED: u64 = 0x00C1_7E5E_ED00_2025;

/// Side of a block (sidewalk slab), metres.
const BLOCK: f32 = 84.0;
/// Width of a street, metres.
const STREET: f32 = 16.0;
/// Block plus street: the grid period.
const CELL: f32 = BLOCK + STREET;
/// Width of the sidewalk between the slab's edge and the lots.
const SIDEWALK: f32 = 4.0;
/// Height of the sidewalk slab.
const SLAB: f32 = 0.15;
/// Width of the grass margin around the city.
const MARGIN: f32 = 600.0;
/// Height of road paint above the street.
const PAINT: f32 = 0.01;
/// Facade triangles per block at the intended 3 m window pitch (sets the grid size).
const TRIS_PER_BLOCK: f64 = 30_000.0;
/// Budgets from here on get street furniture and rooftop units.
const DETAIL_FROM: u32 = 10_000;

/// Parse a `city` spec: `None` if `spec` is not one (not `city` and not starting with `city:`,
/// ASCII case-insensitive), else its triangle budget (`city` alone is [`DEFAULT_TRIANGLES`];
/// `city:N` takes digits with an optional `k` (x1,000) or `M` (x1,000,000) suffix) or a
/// [`SceneError::Parse`] naming the spec and the problem.
pub fn parse_spec(spec: &str) -> Option<Result<u32, SceneError>> {
    if spec.eq_ignore_ascii_case("city") {
        return Some(Ok(DEFAULT_TRIANGLES));
    }
    let prefix = spec.as_bytes().get(..5)?;
    if !prefix.eq_ignore_ascii_case(b"city:") {
        return None;
    }
    let fail = |reason: String| {
        Some(Err(SceneError::Parse {
            path: format!("scene '{spec}'"),
            reason,
        }))
    };
    let budget = &spec[5..];
    let (digits, scale) = match budget.as_bytes().last() {
        Some(b'k' | b'K') => (&budget[..budget.len() - 1], 1_000),
        Some(b'm' | b'M') => (&budget[..budget.len() - 1], 1_000_000),
        _ => (budget, 1),
    };
    if budget.is_empty() {
        return fail("no triangle budget after 'city:' (e.g. city:250k, city:4M)".into());
    }
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return fail(format!(
            "'{budget}' is not a triangle budget: expected digits with an optional k or M \
             suffix (e.g. city:250k, city:4M, city:1000)"
        ));
    }
    let n = digits
        .parse::<u64>()
        .ok()
        .and_then(|d| d.checked_mul(scale));
    match n {
        Some(n) if n < MIN_TRIANGLES as u64 => fail(format!(
            "triangle budget {n} is below the minimum of {MIN_TRIANGLES}"
        )),
        Some(n) if n <= MAX_TRIANGLES as u64 => Some(Ok(n as u32)),
        _ => fail(format!(
            "triangle budget '{budget}' is above the maximum of 64M ({MAX_TRIANGLES})"
        )),
    }
}

/// The canonical spec of budget `n`: `city:4M`, `city:250k` or `city:1234`.
pub fn spec_name(n: u32) -> String {
    if n.is_multiple_of(1_000_000) {
        format!("city:{}M", n / 1_000_000)
    } else if n.is_multiple_of(1_000) {
        format!("city:{}k", n / 1_000)
    } else {
        format!("city:{n}")
    }
}

/// The city of exactly `n` triangles (see the module documentation), named [`spec_name`]`(n)`:
/// no spheres, sky on, camera above the middle street at the city's near edge looking along it.
///
/// # Panics
/// If `n` is outside `MIN_TRIANGLES..=MAX_TRIANGLES` (use [`parse_spec`] for user input).
pub fn city(n: u32) -> Scene {
    assert!(
        (MIN_TRIANGLES..=MAX_TRIANGLES).contains(&n),
        "city budget {n} outside {MIN_TRIANGLES}..={MAX_TRIANGLES}"
    );
    let plan = Plan::new(n);
    let mut mesh = Mesh::with_capacity(plan.vertices(), plan.triangles());
    plan.emit(&mut mesh);
    Scene {
        name: spec_name(n),
        positions: mesh.positions,
        triangles: mesh.triangles,
        tri_material: mesh.tri_material,
        spheres: Vec::new(),
        materials: materials(),
        camera: plan.camera,
        sky: true,
    }
}

/// A horizontal painted or metal quad just above the street.
#[derive(Debug, Clone, Copy)]
struct Flat {
    /// Extent.
    rect: Rect,
    /// Material.
    material: u32,
}

/// Everything the city holds, decided before any triangle is written, so counts are known
/// exactly beforehand.
struct Plan {
    /// Blocks per side.
    g: u32,
    /// Facades.
    walls: Vec<Wall>,
    /// Roofs with parapets.
    roofs: Vec<Roof>,
    /// Slabs, rooftop units, antennas, lamp posts, the flag pole.
    boxes: Vec<BoxItem>,
    /// Water tanks.
    tanks: Vec<Tank>,
    /// Lane dashes, crosswalk stripes and the chosen manhole covers.
    flats: Vec<Flat>,
    /// The pennant on the flag pole, if the budget is odd.
    pennant: Option<[Vec3; 3]>,
    /// The camera.
    camera: Camera,
}

impl Plan {
    /// The plan of the city of exactly `n` triangles.
    fn new(n: u32) -> Plan {
        let detail = n >= DETAIL_FROM;
        let g = ((n as f64 / TRIS_PER_BLOCK).sqrt().round() as u32).max(1);
        let mut rng = Rng::new(CITY_SEED);
        let mut plan = Plan {
            g,
            walls: Vec::new(),
            roofs: Vec::new(),
            boxes: Vec::new(),
            tanks: Vec::new(),
            flats: Vec::new(),
            pennant: None,
            camera: street_camera(g),
        };
        let mut manholes = Vec::new();
        let mut tallest = (0.0_f32, Rect::inset(block_rect(0, 0), SIDEWALK));
        for bi in 0..g {
            for bj in 0..g {
                let block = block_rect(bi, bj);
                plan.boxes.push(BoxItem {
                    lo: Vec3::new(block.x0, 0.0, block.z0),
                    hi: Vec3::new(block.x1, SLAB, block.z1),
                    material: CONCRETE,
                    bottom: false,
                });
                let centre = (g as f32 * CELL + STREET) * 0.5;
                let d = ((block.x0 + BLOCK * 0.5 - centre).hypot(block.z0 + BLOCK * 0.5 - centre)
                    / (centre * std::f32::consts::SQRT_2))
                    .min(1.0);
                let mut lots = Vec::new();
                split_lots(block.inset(SIDEWALK), &mut rng, &mut lots);
                for lot in lots {
                    let top = plan.building(lot, d, detail, &mut rng);
                    if top.0 > tallest.0 {
                        tallest = top;
                    }
                }
                if detail {
                    plan.lamps(block);
                }
            }
        }
        plan.street_paint(detail, &mut manholes);
        // The flag pole on the tallest roof.
        let (top, roof) = tallest;
        let foot = Vec3::new(roof.x0 + 1.0, top - PARAPET, roof.z0 + 1.0);
        let pole_top = foot.y + 8.0;
        plan.boxes.push(BoxItem {
            lo: foot,
            hi: Vec3::new(foot.x + 0.15, pole_top, foot.z + 0.15),
            material: DARK,
            bottom: false,
        });
        plan.fit(n as usize, &manholes, [foot.x + 0.15, pole_top, foot.z]);
        plan
    }

    /// Plan a building on `lot` at relative distance `d` from the centre; returns the height
    /// and roof outline of its top part.
    fn building(&mut self, lot: Rect, d: f32, detail: bool, rng: &mut Rng) -> (f32, Rect) {
        let foot = lot.inset(rng.range(0.8, 2.5));
        let max_h = 25.0 + 175.0 * (1.0 - d) * (1.0 - d);
        let u = rng.unit();
        let h = 8.0 + (max_h - 8.0) * u * u;
        let glass = h > 60.0 && rng.unit() < 0.5;
        let material = if glass {
            DARK
        } else {
            WALL0 + rng.below(WALL_COLOURS.len() as u64) as u32
        };
        let tiered = h > 45.0 && rng.unit() < 0.5;
        let mut parts = vec![(foot, SLAB, SLAB + h)];
        if tiered {
            let base_top = SLAB + h * rng.range(0.35, 0.65);
            let inset = foot.dx().min(foot.dz()) * rng.range(0.12, 0.22);
            parts[0].2 = base_top;
            parts.push((foot.inset(inset), base_top - PARAPET, SLAB + h));
        }
        for &(r, y0, y1) in &parts {
            self.add_part(r, y0, y1, glass, material);
        }
        let (roof, _, top) = parts[parts.len() - 1];
        if detail {
            self.rooftop(roof, top, glass, rng);
        }
        (top, roof)
    }

    /// The four facades and the roof of a box-shaped building part.
    fn add_part(&mut self, r: Rect, y0: f32, y1: f32, glass: bool, material: u32) {
        let height = y1 - y0;
        let sides = [
            (Vec3::new(r.x1, y0, r.z0), Vec3::NEG_X, Vec3::NEG_Z, r.dx()),
            (Vec3::new(r.x0, y0, r.z1), Vec3::X, Vec3::Z, r.dx()),
            (Vec3::new(r.x1, y0, r.z1), Vec3::NEG_Z, Vec3::X, r.dz()),
            (Vec3::new(r.x0, y0, r.z0), Vec3::Z, Vec3::NEG_X, r.dz()),
        ];
        for (origin, right, normal, width) in sides {
            self.walls.push(Wall {
                origin,
                right,
                normal,
                width,
                height,
                glass,
                material,
                cols: 0,
                rows: 0,
            });
        }
        self.roofs.push(Roof { outer: r, top: y1 });
    }

    /// Rooftop units, a water tank on some masonry roofs and an antenna on tall towers.
    fn rooftop(&mut self, roof: Rect, top: f32, glass: bool, rng: &mut Rng) {
        let floor = top - PARAPET;
        let inner = roof.inset(PARAPET_T + 0.4);
        if inner.dx() < 5.0 || inner.dz() < 5.0 {
            return;
        }
        let units = (1 + (inner.dx() * inner.dz() / 300.0) as u32).min(5);
        for _ in 0..units {
            let sx = rng.range(1.2, 3.5).min(inner.dx());
            let sz = rng.range(1.2, 3.5).min(inner.dz());
            let x = rng.range(inner.x0, inner.x1 - sx);
            let z = rng.range(inner.z0, inner.z1 - sz);
            self.boxes.push(BoxItem {
                lo: Vec3::new(x, floor, z),
                hi: Vec3::new(x + sx, floor + rng.range(1.0, 2.2), z + sz),
                material: METAL,
                bottom: false,
            });
        }
        if !glass && inner.dx() >= 8.0 && inner.dz() >= 8.0 && rng.unit() < 0.35 {
            let radius = rng.range(1.2, 2.0);
            self.tanks.push(Tank {
                base: Vec3::new(
                    rng.range(inner.x0 + radius, inner.x1 - radius),
                    floor,
                    rng.range(inner.z0 + radius, inner.z1 - radius),
                ),
                radius,
                height: rng.range(2.0, 3.5),
            });
        }
        if top > 100.0 {
            let c = Vec3::new(
                (inner.x0 + inner.x1) * 0.5,
                floor,
                (inner.z0 + inner.z1) * 0.5,
            );
            self.boxes.push(BoxItem {
                lo: c - Vec3::new(0.3, 0.0, 0.3),
                hi: c + Vec3::new(0.3, rng.range(10.0, 25.0), 0.3),
                material: METAL,
                bottom: false,
            });
        }
    }

    /// Three lamp posts along each side of a block, their heads over the street.
    fn lamps(&mut self, block: Rect) {
        let sides = [
            (Vec3::new(block.x0, SLAB, block.z0), Vec3::X, Vec3::NEG_Z),
            (Vec3::new(block.x0, SLAB, block.z1), Vec3::X, Vec3::Z),
            (Vec3::new(block.x0, SLAB, block.z0), Vec3::Z, Vec3::NEG_X),
            (Vec3::new(block.x1, SLAB, block.z0), Vec3::Z, Vec3::X),
        ];
        for (start, along, out) in sides {
            for k in 0..3 {
                let foot = start + along * (BLOCK * (k as f32 + 0.5) / 3.0) - out * 0.8;
                let half = Vec3::new(0.1, 0.0, 0.1);
                self.boxes.push(BoxItem {
                    lo: foot - half,
                    hi: foot + half + Vec3::Y * 6.0,
                    material: DARK,
                    bottom: false,
                });
                let a = foot + Vec3::Y * 5.8 - along * 0.15;
                let b = foot + Vec3::Y * 6.1 + along * 0.15 + out * 1.6;
                self.boxes.push(BoxItem {
                    lo: a.min(b),
                    hi: a.max(b),
                    material: DARK,
                    bottom: true,
                });
            }
        }
    }

    /// Lane dashes and crosswalks (with `detail`) and the manhole slots, on every street
    /// segment between two crossings.
    fn street_paint(&mut self, detail: bool, manholes: &mut Vec<Rect>) {
        for i in 0..=self.g {
            for j in 0..self.g {
                // Segment along z at x-street i, beside block row j, and its transpose.
                let c = i as f32 * CELL + STREET * 0.5;
                let s0 = j as f32 * CELL + STREET;
                for along_z in [true, false] {
                    let rect = |a0: f32, a1: f32, c0: f32, c1: f32| {
                        if along_z {
                            Rect {
                                x0: c0,
                                z0: a0,
                                x1: c1,
                                z1: a1,
                            }
                        } else {
                            Rect {
                                x0: a0,
                                z0: c0,
                                x1: a1,
                                z1: c1,
                            }
                        }
                    };
                    if detail {
                        for k in 0..14 {
                            let a = s0 + 6.5 + 5.0 * k as f32;
                            self.flats.push(Flat {
                                rect: rect(a, a + 2.5, c - 0.08, c + 0.08),
                                material: PAINT_WHITE,
                            });
                        }
                        for end in [s0 + 1.0, s0 + BLOCK - 4.0] {
                            for k in 0..6 {
                                let x = c - STREET * 0.5 + 1.5 + 2.3 * k as f32;
                                self.flats.push(Flat {
                                    rect: rect(end, end + 3.0, x, x + 1.0),
                                    material: PAINT_WHITE,
                                });
                            }
                        }
                    }
                    for k in 0..8 {
                        let a = s0 + 8.0 + 9.5 * k as f32;
                        let off = if k % 2 == 0 { -3.5 } else { 3.5 };
                        manholes.push(rect(a, a + 0.8, c + off - 0.4, c + off + 0.4));
                    }
                }
            }
        }
    }

    /// Choose the window grids, extra columns/rows, manholes and the pennant so the city has
    /// exactly `n` triangles (`pennant_at`: the top of the flag pole).
    fn fit(&mut self, n: usize, manholes: &[Rect], pennant_at: [f32; 3]) {
        let fixed = self.triangles();
        let plain: usize = self.walls.iter().map(|_| Wall::tris(0, 0)).sum();
        let budget = n.saturating_sub(fixed - plain);
        let facades = |walls: &[Wall], pitch: f64| -> usize {
            walls
                .iter()
                .map(|w| {
                    let (c, r) = w.grid_at(pitch);
                    Wall::tris(c, r)
                })
                .sum()
        };
        // Smallest pitch whose facades fit the budget (facade triangles fall as pitch grows).
        let (mut lo, mut hi) = (0.25_f64, 1.0e6_f64);
        if facades(&self.walls, lo) > budget {
            for _ in 0..64 {
                let mid = (lo * hi).sqrt();
                if facades(&self.walls, mid) > budget {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
        } else {
            hi = lo;
        }
        let mut left = budget;
        for w in &mut self.walls {
            (w.cols, w.rows) = w.grid_at(hi);
            left = left.saturating_sub(Wall::tris(w.cols, w.rows));
        }
        // Top up: one more column or row on walls while it fits, round-robin.
        let mut changed = true;
        while changed {
            changed = false;
            for w in &mut self.walls {
                let now = Wall::tris(w.cols, w.rows);
                let grow = if w.cols == 0 {
                    (1, 1)
                } else if w.cols as f32 / w.width <= w.rows as f32 / w.height {
                    (w.cols + 1, w.rows)
                } else {
                    (w.cols, w.rows + 1)
                };
                let extra = Wall::tris(grow.0, grow.1) - now;
                if extra <= left {
                    (w.cols, w.rows) = grow;
                    left -= extra;
                    changed = true;
                }
            }
        }
        let covers = (left / 2).min(manholes.len());
        for k in 0..covers {
            self.flats.push(Flat {
                rect: manholes[k * manholes.len() / covers],
                material: METAL,
            });
        }
        left -= 2 * covers;
        if left == 1 {
            let [x, y, z] = pennant_at;
            self.pennant = Some([
                Vec3::new(x, y, z),
                Vec3::new(x, y - 1.2, z),
                Vec3::new(x + 2.0, y - 0.6, z),
            ]);
        }
    }

    /// Ground triangles and vertices: the street grid minus the blocks, and the grass margin.
    fn ground_counts(&self) -> (usize, usize) {
        let g = self.g as usize;
        let lines = 2 * g + 2;
        ((lines - 1).pow(2) * 2 - g * g * 2 + 8, lines * lines + 8)
    }

    /// Triangles of the planned city.
    fn triangles(&self) -> usize {
        let walls: usize = self.walls.iter().map(|w| Wall::tris(w.cols, w.rows)).sum();
        let boxes: usize = self
            .boxes
            .iter()
            .map(|b| if b.bottom { 12 } else { 10 })
            .sum();
        self.ground_counts().0
            + walls
            + boxes
            + 18 * self.roofs.len()
            + 22 * self.tanks.len()
            + 2 * self.flats.len()
            + usize::from(self.pennant.is_some())
    }

    /// Vertices of the planned city.
    fn vertices(&self) -> usize {
        let walls: usize = self.walls.iter().map(|w| Wall::verts(w.cols, w.rows)).sum();
        self.ground_counts().1
            + walls
            + 8 * self.boxes.len()
            + 12 * self.roofs.len()
            + 16 * self.tanks.len()
            + 4 * self.flats.len()
            + 3 * usize::from(self.pennant.is_some())
    }

    /// Write the planned geometry.
    fn emit(&self, mesh: &mut Mesh) {
        self.emit_ground(mesh);
        for w in &self.walls {
            mesh.wall(w);
        }
        for r in &self.roofs {
            mesh.roof(r);
        }
        for b in &self.boxes {
            mesh.cuboid(b);
        }
        for t in &self.tanks {
            mesh.tank(t);
        }
        for f in &self.flats {
            let [a, b, c, d] = f.rect.corners(PAINT).map(|p| mesh.vertex(p));
            mesh.quad([a, b, c, d], f.material);
        }
        if let Some(p) = self.pennant {
            let v = p.map(|p| mesh.vertex(p));
            mesh.triangle(v, FLAG);
        }
    }

    /// The asphalt grid (street tiles, not under blocks) and the grass margin around it.
    fn emit_ground(&self, mesh: &mut Mesh) {
        let g = self.g as usize;
        let lines: Vec<f32> = (0..=g)
            .flat_map(|i| [i as f32 * CELL, i as f32 * CELL + STREET])
            .collect();
        let n = lines.len();
        let base = mesh.positions.len() as u32;
        for &z in &lines {
            for &x in &lines {
                mesh.vertex(Vec3::new(x, 0.0, z));
            }
        }
        let at = |ix: usize, iz: usize| base + (iz * n + ix) as u32;
        for iz in 0..n - 1 {
            for ix in 0..n - 1 {
                if ix % 2 == 1 && iz % 2 == 1 {
                    continue; // a block's slab covers it
                }
                mesh.quad(
                    [
                        at(ix, iz),
                        at(ix, iz + 1),
                        at(ix + 1, iz + 1),
                        at(ix + 1, iz),
                    ],
                    ASPHALT,
                );
            }
        }
        let extent = lines[n - 1];
        let inner = Rect {
            x0: 0.0,
            z0: 0.0,
            x1: extent,
            z1: extent,
        };
        let i = inner.corners(0.0).map(|p| mesh.vertex(p));
        let o = inner.inset(-MARGIN).corners(0.0).map(|p| mesh.vertex(p));
        for k in 0..4 {
            let l = (k + 1) % 4;
            mesh.quad([o[k], o[l], i[l], i[k]], GRASS);
        }
    }
}

/// The slab of block `(bi, bj)`.
fn block_rect(bi: u32, bj: u32) -> Rect {
    let x0 = bi as f32 * CELL + STREET;
    let z0 = bj as f32 * CELL + STREET;
    Rect {
        x0,
        z0,
        x1: x0 + BLOCK,
        z1: z0 + BLOCK,
    }
}

/// Split a block's building area into lots by random guillotine cuts (lots 14-45 m).
fn split_lots(r: Rect, rng: &mut Rng, out: &mut Vec<Rect>) {
    let along_x = r.dx() >= r.dz();
    let long = r.dx().max(r.dz());
    if long > 45.0 || (long > 28.0 && rng.unit() < 0.6) {
        let t = rng.range(0.35, 0.65) * long;
        let (a, b) = if along_x {
            (Rect { x1: r.x0 + t, ..r }, Rect { x0: r.x0 + t, ..r })
        } else {
            (Rect { z1: r.z0 + t, ..r }, Rect { z0: r.z0 + t, ..r })
        };
        split_lots(a, rng, out);
        split_lots(b, rng, out);
    } else {
        out.push(r);
    }
}

/// The camera: above the middle street at the city's near edge, looking along it.
fn street_camera(g: u32) -> Camera {
    let extent = g as f32 * CELL + STREET;
    let x = (g / 2) as f32 * CELL + STREET * 0.5;
    Camera {
        eye: Vec3::new(x - 2.0, 22.0, -25.0),
        look_at: Vec3::new(x + 1.0, 8.0, extent * 0.6),
        up: Vec3::Y,
        fov_y_deg: 55.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_budget_in_a_sweep_is_planned_exactly() {
        let mut budgets: Vec<u32> = vec![1_000, 1_001, 1_999, 9_999, 10_000, 10_001];
        budgets.extend((0..60).map(|k| 1_000 + k * 7_919));
        budgets.extend([
            250_000,
            1_000_000,
            1_000_003,
            4_000_000,
            16_000_001,
            MAX_TRIANGLES,
        ]);
        for n in budgets {
            let plan = Plan::new(n);
            assert_eq!(plan.triangles(), n as usize, "budget {n}");
        }
    }

    #[test]
    fn canonical_names() {
        assert_eq!(spec_name(4_000_000), "city:4M");
        assert_eq!(spec_name(250_000), "city:250k");
        assert_eq!(spec_name(1_234), "city:1234");
    }
}
