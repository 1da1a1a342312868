//! Geometry of the generated city: materials, the building blocks the plan is made of
//! (rectangles, facades, boxes, tanks, roofs) and the mesh writer that turns them into shared
//! vertices and triangles.

use glam::Vec3;

use crate::model::scene::Material;

/// Height of a roof's parapet above the roof floor.
pub(super) const PARAPET: f32 = 1.0;
/// Thickness of a parapet.
pub(super) const PARAPET_T: f32 = 0.35;

/// Storey height over window pitch.
pub(super) const ROW_ASPECT: f64 = 1.2;

/// Material indices (into [`materials`]): street asphalt.
pub(super) const ASPHALT: u32 = 1;
/// Sidewalk concrete.
pub(super) const CONCRETE: u32 = 2;
/// Grass margin.
pub(super) const GRASS: u32 = 3;
/// Road paint.
pub(super) const PAINT_WHITE: u32 = 4;
/// Roof tar.
pub(super) const ROOF: u32 = 5;
/// Rooftop units, antennas and manholes: rough metal.
pub(super) const METAL: u32 = 6;
/// Lamp posts and glass-tower mullions.
pub(super) const DARK: u32 = 7;
/// Window panes of masonry buildings.
pub(super) const WINDOW: u32 = 8;
/// Curtain-wall glass of towers.
pub(super) const TOWER_GLASS: u32 = 9;
/// The pennant.
pub(super) const FLAG: u32 = 10;
/// First of the [`WALL_COLOURS`] facade materials.
pub(super) const WALL0: u32 = 11;
/// Facade colours of masonry buildings: brick, sandstone, concrete, plaster, slate.
pub(super) const WALL_COLOURS: [[f32; 3]; 5] = [
    [0.55, 0.25, 0.18],
    [0.75, 0.64, 0.47],
    [0.58, 0.58, 0.56],
    [0.80, 0.78, 0.73],
    [0.30, 0.31, 0.34],
];

/// The material table (index 0 is [`Material::DEFAULT`]).
pub(super) fn materials() -> Vec<Material> {
    let lambert = |r, g, b| Material::Lambertian {
        albedo: Vec3::new(r, g, b),
    };
    let mut m = vec![
        Material::DEFAULT,
        lambert(0.10, 0.10, 0.11),
        lambert(0.52, 0.51, 0.49),
        lambert(0.20, 0.34, 0.12),
        lambert(0.85, 0.85, 0.80),
        lambert(0.18, 0.18, 0.19),
        Material::Metal {
            albedo: Vec3::splat(0.60),
            fuzz: 0.40,
        },
        lambert(0.08, 0.08, 0.09),
        Material::Metal {
            albedo: Vec3::new(0.45, 0.50, 0.55),
            fuzz: 0.05,
        },
        Material::Metal {
            albedo: Vec3::new(0.35, 0.48, 0.60),
            fuzz: 0.02,
        },
        lambert(0.70, 0.05, 0.05),
    ];
    m.extend(WALL_COLOURS.iter().map(|&[r, g, b]| lambert(r, g, b)));
    m
}

/// An axis-aligned rectangle in the ground plane (`x`, `z`).
#[derive(Debug, Clone, Copy)]
pub(super) struct Rect {
    /// Lower corner.
    pub(super) x0: f32,
    /// Lower corner.
    pub(super) z0: f32,
    /// Upper corner.
    pub(super) x1: f32,
    /// Upper corner.
    pub(super) z1: f32,
}

impl Rect {
    /// The rectangle shrunk by `d` on every side.
    pub(super) fn inset(self, d: f32) -> Rect {
        Rect {
            x0: self.x0 + d,
            z0: self.z0 + d,
            x1: self.x1 - d,
            z1: self.z1 - d,
        }
    }

    /// Width along x.
    pub(super) fn dx(&self) -> f32 {
        self.x1 - self.x0
    }

    /// Depth along z.
    pub(super) fn dz(&self) -> f32 {
        self.z1 - self.z0
    }

    /// Corners counter-clockwise seen from above (+Y normal for a fan) at height `y`.
    pub(super) fn corners(&self, y: f32) -> [Vec3; 4] {
        [
            Vec3::new(self.x0, y, self.z0),
            Vec3::new(self.x0, y, self.z1),
            Vec3::new(self.x1, y, self.z1),
            Vec3::new(self.x1, y, self.z0),
        ]
    }
}

/// A facade: a vertical rectangle seen from outside, with a `cols x rows` window grid (both 0
/// for a plain wall).
#[derive(Debug, Clone, Copy)]
pub(super) struct Wall {
    /// Bottom-left corner seen from outside.
    pub(super) origin: Vec3,
    /// Unit vector to the right seen from outside (`Y x normal`).
    pub(super) right: Vec3,
    /// Outward unit normal.
    pub(super) normal: Vec3,
    /// Width along `right`.
    pub(super) width: f32,
    /// Height of the wall.
    pub(super) height: f32,
    /// Glass tower (curtain wall) rather than masonry.
    pub(super) glass: bool,
    /// Material of the wall surface and window reveals.
    pub(super) material: u32,
    /// Window columns.
    pub(super) cols: u32,
    /// Window rows.
    pub(super) rows: u32,
}

impl Wall {
    /// Window columns and rows at window pitch `pitch` (0 x 0 if either is 0).
    pub(super) fn grid_at(&self, pitch: f64) -> (u32, u32) {
        let c = (self.width as f64 / pitch).floor().min(1e6) as u32;
        let r = ((self.height - PARAPET) as f64 / (pitch * ROW_ASPECT))
            .floor()
            .min(1e6) as u32;
        if c == 0 || r == 0 {
            (0, 0)
        } else {
            (c, r)
        }
    }

    /// Triangles of a wall with a `c x r` window grid.
    pub(super) fn tris(c: u32, r: u32) -> usize {
        let (c, r) = (c as usize, r as usize);
        if c == 0 {
            2
        } else {
            16 * c * r + 4 * c + 4 * r + 2
        }
    }

    /// Vertices of a wall with a `c x r` window grid.
    pub(super) fn verts(c: u32, r: u32) -> usize {
        let (c, r) = (c as usize, r as usize);
        if c == 0 {
            4
        } else {
            (2 * c + 2) * (2 * r + 2) + 4 * c * r
        }
    }
}

/// A box; without `bottom` it stands on something and has no bottom face.
#[derive(Debug, Clone, Copy)]
pub(super) struct BoxItem {
    /// Lower corner.
    pub(super) lo: Vec3,
    /// Upper corner.
    pub(super) hi: Vec3,
    /// Material.
    pub(super) material: u32,
    /// Whether the bottom face is drawn.
    pub(super) bottom: bool,
}

/// An octagonal water tank standing at `base`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tank {
    /// Centre of the bottom.
    pub(super) base: Vec3,
    /// Circumradius.
    pub(super) radius: f32,
    /// Height.
    pub(super) height: f32,
}

/// A flat roof inside a parapet: `outer` at the parapet top `top`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Roof {
    /// Outline of the building part.
    pub(super) outer: Rect,
    /// Height of the parapet top.
    pub(super) top: f32,
}

/// The growing geometry buffers.
pub(super) struct Mesh {
    /// Vertex positions.
    pub(super) positions: Vec<Vec3>,
    /// Triangles.
    pub(super) triangles: Vec<[u32; 3]>,
    /// Material per triangle.
    pub(super) tri_material: Vec<u32>,
}

impl Mesh {
    /// Empty buffers with room for the planned geometry.
    pub(super) fn with_capacity(vertices: usize, triangles: usize) -> Mesh {
        Mesh {
            positions: Vec::with_capacity(vertices),
            triangles: Vec::with_capacity(triangles),
            tri_material: Vec::with_capacity(triangles),
        }
    }

    /// Add a vertex; returns its index.
    pub(super) fn vertex(&mut self, p: Vec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Add one triangle.
    pub(super) fn triangle(&mut self, v: [u32; 3], material: u32) {
        self.triangles.push(v);
        self.tri_material.push(material);
    }

    /// Add the quad `q` (counter-clockwise seen from its front) as two triangles.
    pub(super) fn quad(&mut self, q: [u32; 4], material: u32) {
        self.triangle([q[0], q[1], q[2]], material);
        self.triangle([q[0], q[2], q[3]], material);
    }

    /// A facade: the wall grid with window holes, each window's four reveals and its pane.
    pub(super) fn wall(&mut self, w: &Wall) {
        let at = |u: f32, y: f32| w.origin + w.right * u + Vec3::Y * y;
        if w.cols == 0 {
            let v = [
                at(0.0, 0.0),
                at(w.width, 0.0),
                at(w.width, w.height),
                at(0.0, w.height),
            ]
            .map(|p| self.vertex(p));
            self.quad(v, w.material);
            return;
        }
        let (fx, fy, depth, pane) = if w.glass {
            (0.86, 0.80, 0.12, TOWER_GLASS)
        } else {
            (0.55, 0.55, 0.25, WINDOW)
        };
        let lines = |count: u32, span: f32, end: f32, frac: f32| -> Vec<f32> {
            let cell = span / count as f32;
            let mut v = vec![0.0];
            for i in 0..count {
                let a = cell * i as f32 + cell * (1.0 - frac) * 0.5;
                v.extend([a, a + cell * frac]);
            }
            v.push(end);
            v
        };
        let us = lines(w.cols, w.width, w.width, fx);
        let ys = lines(w.rows, w.height - PARAPET, w.height, fy);
        let nu = us.len();
        let base = self.positions.len() as u32;
        for &y in &ys {
            for &u in &us {
                self.vertex(at(u, y));
            }
        }
        let grid = |iu: usize, iy: usize| base + (iy * nu + iu) as u32;
        let back = -w.normal * depth;
        for iy in 0..ys.len() - 1 {
            for iu in 0..nu - 1 {
                let [bl, br, tr, tl] = [
                    grid(iu, iy),
                    grid(iu + 1, iy),
                    grid(iu + 1, iy + 1),
                    grid(iu, iy + 1),
                ];
                if iu % 2 == 0 || iy % 2 == 0 {
                    self.quad([bl, br, tr, tl], w.material);
                    continue;
                }
                let [pbl, pbr, ptr, ptl] = [
                    at(us[iu], ys[iy]),
                    at(us[iu + 1], ys[iy]),
                    at(us[iu + 1], ys[iy + 1]),
                    at(us[iu], ys[iy + 1]),
                ]
                .map(|p| self.vertex(p + back));
                self.quad([bl, pbl, ptl, tl], w.material); // left reveal, faces right
                self.quad([br, tr, ptr, pbr], w.material); // right reveal, faces left
                self.quad([bl, br, pbr, pbl], w.material); // sill, faces up
                self.quad([tl, ptl, ptr, tr], w.material); // lintel, faces down
                self.quad([pbl, pbr, ptr, ptl], pane);
            }
        }
    }

    /// A roof: parapet top ring, parapet inner walls and the roof floor.
    pub(super) fn roof(&mut self, r: &Roof) {
        let inner = r.outer.inset(PARAPET_T);
        let o = r.outer.corners(r.top).map(|p| self.vertex(p));
        let i = inner.corners(r.top).map(|p| self.vertex(p));
        let f = inner.corners(r.top - PARAPET).map(|p| self.vertex(p));
        for k in 0..4 {
            let l = (k + 1) % 4;
            self.quad([o[k], o[l], i[l], i[k]], ROOF);
            self.quad([f[k], i[k], i[l], f[l]], ROOF);
        }
        self.quad(f, ROOF);
    }

    /// A box with outward-facing sides and top (and bottom if asked).
    pub(super) fn cuboid(&mut self, b: &BoxItem) {
        let c: [u32; 8] = std::array::from_fn(|i| {
            let pick = |bit: usize, l: f32, h: f32| if i & bit != 0 { h } else { l };
            self.vertex(Vec3::new(
                pick(1, b.lo.x, b.hi.x),
                pick(2, b.lo.y, b.hi.y),
                pick(4, b.lo.z, b.hi.z),
            ))
        });
        let m = b.material;
        self.quad([c[0], c[4], c[6], c[2]], m);
        self.quad([c[1], c[3], c[7], c[5]], m);
        self.quad([c[2], c[6], c[7], c[3]], m);
        self.quad([c[0], c[2], c[3], c[1]], m);
        self.quad([c[4], c[5], c[7], c[6]], m);
        if b.bottom {
            self.quad([c[0], c[1], c[5], c[4]], m);
        }
    }

    /// An octagonal prism with a top.
    pub(super) fn tank(&mut self, t: &Tank) {
        let ring = |mesh: &mut Mesh, y: f32| -> [u32; 8] {
            std::array::from_fn(|k| {
                let a = (k as f32 + 0.5) * std::f32::consts::FRAC_PI_4;
                mesh.vertex(t.base + Vec3::new(t.radius * a.cos(), y, t.radius * a.sin()))
            })
        };
        let bottom = ring(self, 0.0);
        let top = ring(self, t.height);
        for k in 0..8 {
            let l = (k + 1) % 8;
            self.quad([bottom[k], top[k], top[l], bottom[l]], METAL);
        }
        for k in 1..7 {
            self.triangle([top[0], top[k + 1], top[k]], METAL);
        }
    }
}
