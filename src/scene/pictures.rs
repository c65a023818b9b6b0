//! UV-layout pictures: a geometry's triangles drawn in texture space, filled by what the core
//! found in them, as an SVG a person opens in a browser or attaches to a bug report, or as a PNG
//! of that same SVG.
//!
//! Each geometry is a panel: a title (the file, the primitives, the UV set), the texture square
//! 0–1 and any tiles the UVs reach beyond it, the triangles, and a legend whose counts are the
//! report's (the same triangle test makes both).
//!
//! - **Fills, one class per triangle**, in this order of precedence: degenerate (no area in
//!   space, two corners at one position, or non-finite values), zero UV area (drawn as outlines:
//!   they have no area to fill), mirrored UVs, ordinary. Triangles whose tangents were repaired
//!   get a second outline over their fill; vertices where handedness flips get a dot.
//! - **Bounded files.** Each class is one `<path>`. Up to [`VECTOR_TRIANGLES`] triangles a panel
//!   draws every triangle exactly; beyond that it draws each class's coverage of a
//!   [`GRID`]×[`GRID`] grid (one pixel of the panel) as runs along rows, so a 2M-triangle mesh
//!   makes a file bounded by the grid (at most `GRID` rows of runs per class), not by the mesh.
//!   The work of that grid is one span per triangle and row it covers.
//! - **PNG** is the SVG drawn by `resvg` (a pure-Rust SVG renderer on `tiny-skia`), with the
//!   DejaVu Sans subset embedded in the binary: the two formats cannot differ, and nothing is
//!   shelled out to or read from the system's fonts. tiny-skia alone would draw the shapes but
//!   not the legend's text.

use super::error::{ProblemCode, SceneError};
use super::layout::Layout;
use super::report::thousands;
use resvg::{tiny_skia, usvg};
use std::fmt::Write;
use tspace_tangent::TriangleMarks;

/// The size of a panel's drawing, in pixels.
const PANEL: f64 = 1024.0;
/// Cells per side of the grid that large meshes are drawn on: one per pixel.
pub const GRID: usize = 1024;
/// Up to this many triangles a panel draws each triangle as it is.
pub const VECTOR_TRIANGLES: usize = 100_000;
/// The most grid rows (and outline cells) one panel's triangles may cost: a little under a second
/// of work. A mesh of huge overlapping triangles would otherwise cost rows × triangles; past
/// this, triangles are marked at their corners only, and the legend says so.
const GRID_WORK: u64 = 1 << 26;
/// At most this many panels in one picture; the rest are named in a note.
pub const MAX_PANELS: usize = 8;
/// How many whole tiles beyond 0–1 are drawn at most, in each direction.
const MAX_TILES_BEYOND: f64 = 8.0;

const MARGIN: f64 = 24.0;
const HEADER: f64 = 64.0;
const LEGEND_ROW: f64 = 22.0;
const WIDTH: f64 = PANEL + 2.0 * MARGIN;

/// The font the PNG is drawn with (see `scripts/make-font-subset`).
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-Latin.ttf");

/// A fill class, in order of precedence (higher wins).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Fill {
    Ordinary = 1,
    Mirrored = 2,
    ZeroUvArea = 3,
    Degenerate = 4,
}

impl Fill {
    const ALL: [Fill; 4] = [
        Fill::Ordinary,
        Fill::Mirrored,
        Fill::ZeroUvArea,
        Fill::Degenerate,
    ];

    fn of(marks: TriangleMarks) -> Fill {
        if marks.is_degenerate() {
            Fill::Degenerate
        } else if marks.has(TriangleMarks::ZERO_UV_AREA) {
            Fill::ZeroUvArea
        } else if marks.has(TriangleMarks::MIRRORED_UV) {
            Fill::Mirrored
        } else {
            Fill::Ordinary
        }
    }

    /// The path's presentation attributes: fills for classes with area, outlines for the one
    /// without.
    fn style(self, vector: bool) -> &'static str {
        match (self, vector) {
            (Fill::Ordinary, true) => {
                r##"fill="#c9c9c9" stroke="#8c8c8c" stroke-width="0.3" stroke-linejoin="round""##
            }
            (Fill::Mirrored, true) => {
                r##"fill="url(#mirrored)" stroke="#1f6f9f" stroke-width="0.3" stroke-linejoin="round""##
            }
            (Fill::ZeroUvArea, true) => {
                r##"fill="none" stroke="#e69f00" stroke-width="1.5" stroke-linejoin="round""##
            }
            (Fill::Degenerate, true) => {
                r##"fill="#d55e00" stroke="#d55e00" stroke-width="1" stroke-linejoin="round""##
            }
            (Fill::Ordinary, false) => r##"fill="#c9c9c9""##,
            (Fill::Mirrored, false) => r##"fill="url(#mirrored)""##,
            (Fill::ZeroUvArea, false) => r##"fill="#e69f00""##,
            (Fill::Degenerate, false) => r##"fill="#d55e00""##,
        }
    }

    fn swatch(self) -> &'static str {
        match self {
            Fill::Ordinary => "#c9c9c9",
            Fill::Mirrored => "url(#mirrored)",
            Fill::ZeroUvArea => "#e69f00",
            Fill::Degenerate => "#d55e00",
        }
    }
}

const REPAIRED_COLOUR: &str = "#cc79a7";
const FLIP_COLOUR: &str = "#000000";

/// The texture-space window a panel shows: whole tiles, 0–1 always among them.
#[derive(Clone, Copy, Debug)]
struct Window {
    u0: f64,
    v0: f64,
    /// Tiles across and down.
    tiles_u: f64,
    tiles_v: f64,
    /// Pixels per UV unit.
    scale: f64,
}

impl Window {
    fn of(layout: &Layout) -> Window {
        let (mut min, mut max) = ([0.0f64; 2], [1.0f64; 2]);
        for uv in &layout.uvs {
            if uv[0].is_finite() && uv[1].is_finite() {
                for axis in 0..2 {
                    min[axis] = min[axis].min(uv[axis] as f64);
                    max[axis] = max[axis].max(uv[axis] as f64);
                }
            }
        }
        let low = |x: f64| x.floor().max(-MAX_TILES_BEYOND);
        let high = |x: f64| x.ceil().min(1.0 + MAX_TILES_BEYOND);
        let (u0, v0) = (low(min[0]), low(min[1]));
        let (tiles_u, tiles_v) = (high(max[0]) - u0, high(max[1]) - v0);
        Window {
            u0,
            v0,
            tiles_u,
            tiles_v,
            scale: PANEL / tiles_u.max(tiles_v),
        }
    }

    /// Pixels from the panel's top left. glTF's texture origin is the top left, v downwards,
    /// as an image's rows: the picture lies as the texture does.
    fn point(&self, uv: [f32; 2]) -> [f64; 2] {
        [
            (uv[0] as f64 - self.u0) * self.scale,
            (uv[1] as f64 - self.v0) * self.scale,
        ]
    }

    fn width(&self) -> f64 {
        self.tiles_u * self.scale
    }

    fn height(&self) -> f64 {
        self.tiles_v * self.scale
    }

    /// Whether the UVs reach beyond the tiles drawn.
    fn clips(&self, layout: &Layout) -> bool {
        layout.uvs.iter().any(|uv| {
            let [x, y] = self.point(*uv);
            x < -0.5 || y < -0.5 || x > self.width() + 0.5 || y > self.height() + 0.5
        })
    }
}

/// What a picture is of: the scene file's name, for titles.
pub struct Subject<'a> {
    pub file: &'a str,
}

/// The picture formats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PictureFormat {
    #[default]
    Svg,
    Png,
}

impl PictureFormat {
    pub fn media_type(self) -> &'static str {
        match self {
            PictureFormat::Svg => "image/svg+xml",
            PictureFormat::Png => "image/png",
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            PictureFormat::Svg => "svg",
            PictureFormat::Png => "png",
        }
    }
}

impl std::str::FromStr for PictureFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "svg" => Ok(PictureFormat::Svg),
            "png" => Ok(PictureFormat::Png),
            _ => Err(format!("{s:?} is not a picture format; use svg or png")),
        }
    }
}

/// Which geometries to draw: those of one mesh (by index or name), or of one primitive of it;
/// by default every one that was computed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Selection {
    pub mesh: Option<MeshRef>,
    pub primitive: Option<usize>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshRef {
    Index(usize),
    Name(String),
}

impl Selection {
    /// From the `mesh` and `primitive` values of a query or the command line: a mesh is an index
    /// or a name, a primitive an index within it (and needs a mesh).
    pub fn parse(mesh: Option<&str>, primitive: Option<&str>) -> Result<Selection, String> {
        let mesh = mesh.map(|m| match m.parse::<usize>() {
            Ok(index) => MeshRef::Index(index),
            Err(_) => MeshRef::Name(m.to_owned()),
        });
        let primitive = primitive
            .map(|p| {
                p.parse::<usize>()
                    .map_err(|_| format!("primitive: {p:?} is not an index (0, 1, ...)"))
            })
            .transpose()?;
        if primitive.is_some() && mesh.is_none() {
            return Err("primitive needs a mesh too (mesh=0&primitive=1)".into());
        }
        Ok(Selection { mesh, primitive })
    }

    fn takes(&self, layout: &Layout) -> bool {
        layout.primitives.iter().any(|p| {
            let mesh = match &self.mesh {
                None => true,
                Some(MeshRef::Index(i)) => p.mesh == *i,
                Some(MeshRef::Name(name)) => p.mesh_name.as_deref() == Some(name.as_str()),
            };
            mesh && self.primitive.is_none_or(|i| p.primitive == i)
        })
    }

    fn describe(&self) -> String {
        let mesh = match &self.mesh {
            None => "any mesh".to_owned(),
            Some(MeshRef::Index(i)) => format!("meshes[{i}]"),
            Some(MeshRef::Name(name)) => format!("the mesh named {name:?}"),
        };
        match self.primitive {
            Some(p) => format!("{mesh}, primitive {p}"),
            None => mesh,
        }
    }
}

/// The picture of the selected `layouts`, in `format`.
pub fn draw(
    subject: &Subject<'_>,
    layouts: &[Layout],
    selection: &Selection,
    format: PictureFormat,
) -> Result<Vec<u8>, SceneError> {
    if layouts.is_empty() {
        return Err(SceneError::new(
            ProblemCode::NothingToDraw,
            "no primitive gets tangents from texture coordinates, so there is no layout to draw \
             (all=true draws every triangle primitive with UVs)",
        ));
    }
    let chosen: Vec<Layout> = layouts
        .iter()
        .filter(|layout| selection.takes(layout))
        .cloned()
        .collect();
    if chosen.is_empty() {
        let available: Vec<String> = layouts
            .iter()
            .flat_map(|l| &l.primitives)
            .take(12)
            .map(|p| format!("meshes[{}].primitives[{}]", p.mesh, p.primitive))
            .collect();
        return Err(SceneError::new(
            ProblemCode::NothingToDraw,
            format!(
                "{} has no primitive with a layout; these have: {}",
                selection.describe(),
                available.join(", ")
            ),
        ));
    }
    let svg = svg(subject, &chosen);
    match format {
        PictureFormat::Svg => Ok(svg.into_bytes()),
        PictureFormat::Png => png(&svg)
            .map_err(|e| SceneError::new(ProblemCode::Internal, format!("drawing the PNG: {e}"))),
    }
}

/// The SVG of `layouts`, one panel each (at most [`MAX_PANELS`]).
pub fn svg(subject: &Subject<'_>, layouts: &[Layout]) -> String {
    let shown = &layouts[..layouts.len().min(MAX_PANELS)];
    let panels: Vec<(String, f64)> = shown.iter().map(|layout| panel(subject, layout)).collect();
    let note_height = if layouts.len() > shown.len() {
        28.0
    } else {
        0.0
    };
    let height: f64 = panels.iter().map(|(_, h)| h).sum::<f64>() + note_height;
    let mut out = String::with_capacity(panels.iter().map(|(s, _)| s.len()).sum::<usize>() + 1024);
    let _ = write!(
        out,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" viewBox="0 0 {WIDTH} {height}" font-family="DejaVu Sans, Verdana, sans-serif">"##
    );
    let _ = write!(out, "<title>UV layout of {}</title>", escape(subject.file));
    // Mirrored triangles are hatched, not filled: a mirrored half of a symmetric model usually
    // lies on the same islands as the other half, and the grey shows through the hatching.
    let _ = write!(
        out,
        r##"<defs><pattern id="mirrored" width="6" height="6" patternUnits="userSpaceOnUse" patternTransform="rotate(45)"><rect width="3" height="6" fill="#56b4e9"/></pattern></defs><rect width="{WIDTH}" height="{height}" fill="#ffffff"/>"##
    );
    let mut top = 0.0;
    for (body, panel_height) in &panels {
        let _ = write!(out, r#"<g transform="translate(0 {top})">{body}</g>"#);
        top += panel_height;
    }
    if note_height > 0.0 {
        let _ = write!(
            out,
            r##"<text x="{MARGIN}" y="{}" font-size="14" fill="#333333">{} more geometries not drawn: pick one with mesh= and primitive=.</text>"##,
            top + 18.0,
            layouts.len() - shown.len()
        );
    }
    out.push_str("</svg>\n");
    out
}

/// A PNG of [`svg`]'s picture.
pub fn png(svg: &str) -> Result<Vec<u8>, String> {
    let mut options = usvg::Options::default();
    options.fontdb_mut().load_font_data(FONT.to_vec());
    options.font_family = "DejaVu Sans".into();
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| e.to_string())?;
    let size = tree.size().to_int_size();
    let mut pixmap =
        tiny_skia::Pixmap::new(size.width(), size.height()).ok_or("the picture has no size")?;
    resvg::render(&tree, tiny_skia::Transform::default(), &mut pixmap.as_mut());
    pixmap.encode_png().map_err(|e| e.to_string())
}

/// One panel: its SVG body (in panel coordinates) and its height.
fn panel(subject: &Subject<'_>, layout: &Layout) -> (String, f64) {
    let window = Window::of(layout);
    let mut out = String::new();
    title(&mut out, subject, layout);
    let _ = write!(
        out,
        r#"<g transform="translate({MARGIN} {HEADER})"><clipPath id="{id}"><rect width="{w}" height="{h}"/></clipPath>"#,
        id = clip_id(layout),
        w = window.width(),
        h = window.height()
    );
    tiles(&mut out, &window);
    let _ = write!(out, r#"<g clip-path="url(#{})">"#, clip_id(layout));
    let whole = if layout.triangle_count() <= VECTOR_TRIANGLES {
        vector_triangles(&mut out, layout, &window);
        true
    } else {
        grid_triangles(&mut out, layout, &window)
    };
    finder_rings(&mut out, layout, &window);
    flip_dots(&mut out, layout, &window);
    out.push_str("</g>");
    // The 0–1 square over the triangles, so its edge shows where they cover it.
    let unit = window.point([0.0, 0.0]);
    let _ = write!(
        out,
        r##"<rect x="{:.1}" y="{:.1}" width="{s:.1}" height="{s:.1}" fill="none" stroke="#222222" stroke-width="1.5"/></g>"##,
        unit[0],
        unit[1],
        s = window.scale
    );
    let legend_top = HEADER + window.height() + 16.0;
    let legend_height = legend(&mut out, layout, &window, legend_top, whole);
    (out, legend_top + legend_height + MARGIN)
}

fn clip_id(layout: &Layout) -> String {
    let (mesh, primitive) = layout
        .primitives
        .first()
        .map_or((0, 0), |p| (p.mesh, p.primitive));
    format!("uv-{mesh}-{primitive}")
}

fn title(out: &mut String, subject: &Subject<'_>, layout: &Layout) {
    let mut heading = String::new();
    if let Some(first) = layout.primitives.first() {
        let _ = write!(
            heading,
            "meshes[{}].primitives[{}]",
            first.mesh, first.primitive
        );
        if let Some(name) = &first.mesh_name {
            let _ = write!(heading, " \u{201c}{}\u{201d}", shorten(name, 48));
        }
    }
    let others = layout.primitives.len().saturating_sub(1);
    if others > 0 {
        let _ = write!(heading, " and {others} more sharing its geometry");
    }
    let _ = write!(
        out,
        r##"<text x="{MARGIN}" y="26" font-size="18" font-weight="bold" fill="#111111">{} – {}</text>"##,
        escape(&shorten(subject.file, 60)),
        escape(&heading)
    );
    let _ = write!(
        out,
        r##"<text x="{MARGIN}" y="48" font-size="13" fill="#444444">TEXCOORD_{} · {} · {} · UV layout by tspace {}</text>"##,
        layout.texcoord,
        counted(layout.triangle_count() as u64, "triangle"),
        counted(layout.uvs.len() as u64, "vertex"),
        env!("CARGO_PKG_VERSION")
    );
}

/// The tile grid, with the tiles' corner coordinates along the top and the left.
fn tiles(out: &mut String, window: &Window) {
    let (w, h) = (window.width(), window.height());
    let _ = write!(
        out,
        r##"<rect width="{w}" height="{h}" fill="#fafafa" stroke="#bbbbbb"/>"##
    );
    let mut lines = String::new();
    for i in 1..window.tiles_u as usize {
        let x = i as f64 * window.scale;
        let _ = write!(lines, "M{x:.1} 0V{h:.1}");
    }
    for i in 1..window.tiles_v as usize {
        let y = i as f64 * window.scale;
        let _ = write!(lines, "M0 {y:.1}H{w:.1}");
    }
    if !lines.is_empty() {
        let _ = write!(
            out,
            r##"<path d="{lines}" stroke="#bbbbbb" stroke-dasharray="4 4" fill="none"/>"##
        );
    }
    // Labels only where there is room for them.
    if window.scale >= 48.0 {
        for i in 0..=window.tiles_u as usize {
            let _ = write!(
                out,
                r##"<text x="{:.1}" y="-4" font-size="11" fill="#666666" text-anchor="middle">{}</text>"##,
                i as f64 * window.scale,
                window.u0 + i as f64
            );
        }
        for i in 0..=window.tiles_v as usize {
            let _ = write!(
                out,
                r##"<text x="-4" y="{:.1}" font-size="11" fill="#666666" text-anchor="end">{}</text>"##,
                i as f64 * window.scale + 4.0,
                window.v0 + i as f64
            );
        }
    }
}

/// The triangle's corners in pixels, if all are finite.
fn corners(layout: &Layout, window: &Window, t: usize) -> Option<[[f64; 2]; 3]> {
    let [a, b, c] = layout.triangle(t);
    let uv = |v: usize| {
        let uv = *layout.uvs.get(v)?;
        (uv[0].is_finite() && uv[1].is_finite()).then(|| window.point(uv))
    };
    Some([uv(a)?, uv(b)?, uv(c)?])
}

/// Every triangle as it is: one path per class, and one of repaired outlines.
fn vector_triangles(out: &mut String, layout: &Layout, window: &Window) {
    let mut paths: [String; 4] = Default::default();
    let mut repaired = String::new();
    for (t, &marks) in layout.marks.triangles.iter().enumerate() {
        let Some([a, b, c]) = corners(layout, window, t) else {
            continue;
        };
        let path = &mut paths[Fill::of(marks) as usize - 1];
        let _ = write!(
            path,
            "M{:.1} {:.1}L{:.1} {:.1}L{:.1} {:.1}Z",
            a[0], a[1], b[0], b[1], c[0], c[1]
        );
        if marks.has(TriangleMarks::REPAIRED) {
            let _ = write!(
                repaired,
                "M{:.1} {:.1}L{:.1} {:.1}L{:.1} {:.1}Z",
                a[0], a[1], b[0], b[1], c[0], c[1]
            );
        }
    }
    for fill in Fill::ALL {
        let path = &paths[fill as usize - 1];
        if !path.is_empty() {
            let _ = write!(out, r#"<path d="{path}" {}/>"#, fill.style(true));
        }
    }
    if !repaired.is_empty() {
        let _ = write!(
            out,
            r#"<path d="{repaired}" fill="none" stroke="{REPAIRED_COLOUR}" stroke-width="1.5" stroke-linejoin="round"/>"#
        );
    }
}

/// Coverage of a [`GRID`]×[`GRID`] grid, kept as per-row differences so that marking a span
/// costs two additions whatever its length.
struct Coverage {
    differences: Vec<i32>,
}

impl Coverage {
    fn new() -> Self {
        Coverage {
            differences: vec![0; GRID * (GRID + 1)],
        }
    }

    /// Marks cells `x0..=x1` of row `y` (clamped to the grid).
    fn span(&mut self, y: i64, x0: i64, x1: i64) {
        if y < 0 || y >= GRID as i64 || x1 < 0 || x0 >= GRID as i64 || x1 < x0 {
            return;
        }
        let row = y as usize * (GRID + 1);
        self.differences[row + x0.max(0) as usize] += 1;
        self.differences[row + x1.min(GRID as i64 - 1) as usize + 1] -= 1;
    }

    fn point(&mut self, p: [f64; 2]) {
        let (x, y) = (p[0].floor() as i64, p[1].floor() as i64);
        self.span(y, x, x);
    }

    /// Marks the cells whose centres lie in the triangle, and at least the cells of its corners
    /// (a triangle thinner than a cell would otherwise vanish).
    /// Each row costs one unit of `budget`; a triangle the budget cannot pay for is marked at
    /// its corners only, and `false` returned.
    fn triangle(&mut self, corners: [[f64; 2]; 3], budget: &mut u64) -> bool {
        for p in corners {
            self.point(p);
        }
        let top = corners.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
        let bottom = corners
            .iter()
            .map(|p| p[1])
            .fold(f64::NEG_INFINITY, f64::max);
        let first = ((top - 0.5).ceil() as i64).max(0);
        let last = ((bottom - 0.5).floor() as i64).min(GRID as i64 - 1);
        let rows = (last - first + 1).max(0) as u64;
        if rows > *budget {
            return false;
        }
        *budget -= rows;
        for y in first..=last {
            let centre = y as f64 + 0.5;
            let (mut left, mut right) = (f64::INFINITY, f64::NEG_INFINITY);
            for (p, q) in [(0, 1), (1, 2), (2, 0)].map(|(i, j)| (corners[i], corners[j])) {
                if (p[1] <= centre && centre <= q[1]) || (q[1] <= centre && centre <= p[1]) {
                    let x = if q[1] == p[1] {
                        p[0].min(q[0])
                    } else {
                        p[0] + (centre - p[1]) * (q[0] - p[0]) / (q[1] - p[1])
                    };
                    let x_end = if q[1] == p[1] { p[0].max(q[0]) } else { x };
                    left = left.min(x);
                    right = right.max(x_end);
                }
            }
            if left <= right {
                let x0 = (left - 0.5).ceil() as i64;
                let x1 = (right - 0.5).floor() as i64;
                if x0 <= x1 {
                    self.span(y, x0, x1);
                } else {
                    let x = ((left + right) / 2.0).floor() as i64;
                    self.span(y, x, x);
                }
            }
        }
        true
    }

    /// Marks the cells along the triangle's edges (for triangles with no area to fill), a unit
    /// of `budget` a cell; as [`Coverage::triangle`] when the budget cannot pay.
    fn outline(&mut self, corners: [[f64; 2]; 3], budget: &mut u64) -> bool {
        let edges = [(0, 1), (1, 2), (2, 0)].map(|(i, j)| (corners[i], corners[j]));
        let steps = edges.map(|(p, q)| {
            let steps = (q[0] - p[0]).abs().max((q[1] - p[1]).abs()).ceil();
            steps.clamp(1.0, 4.0 * GRID as f64) as usize
        });
        let cost = steps.iter().map(|&s| s as u64 + 1).sum::<u64>();
        if cost > *budget {
            for p in corners {
                self.point(p);
            }
            return false;
        }
        *budget -= cost;
        for ((p, q), steps) in edges.into_iter().zip(steps) {
            for s in 0..=steps {
                let f = s as f64 / steps as f64;
                self.point([p[0] + f * (q[0] - p[0]), p[1] + f * (q[1] - p[1])]);
            }
        }
        true
    }

    /// Whether each cell is covered, row by row.
    fn cells(&self) -> Vec<bool> {
        let mut covered = vec![false; GRID * GRID];
        for y in 0..GRID {
            let mut sum = 0;
            for x in 0..GRID {
                sum += self.differences[y * (GRID + 1) + x];
                covered[y * GRID + x] = sum > 0;
            }
        }
        covered
    }
}

/// A large mesh: each class's coverage of the grid, a cell going to the class that takes
/// precedence, written as runs along rows.
fn grid_triangles(out: &mut String, layout: &Layout, window: &Window) -> bool {
    // The grid is one pixel a cell when the window is square; a narrower one uses part of it.
    let mut coverage: Vec<Coverage> = Fill::ALL.iter().map(|_| Coverage::new()).collect();
    let mut repaired = Coverage::new();
    let mut budget = GRID_WORK;
    let mut whole = true;
    for (t, &marks) in layout.marks.triangles.iter().enumerate() {
        let Some(corners) = corners(layout, window, t) else {
            continue;
        };
        let fill = Fill::of(marks);
        let grid = &mut coverage[fill as usize - 1];
        whole &= if fill == Fill::ZeroUvArea {
            grid.outline(corners, &mut budget)
        } else {
            grid.triangle(corners, &mut budget)
        };
        if marks.has(TriangleMarks::REPAIRED) {
            whole &= repaired.outline(corners, &mut budget);
        }
    }
    let cells: Vec<Vec<bool>> = coverage.iter().map(Coverage::cells).collect();
    let mut owner = vec![0u8; GRID * GRID];
    for fill in Fill::ALL {
        for (cell, &covered) in owner.iter_mut().zip(&cells[fill as usize - 1]) {
            if covered {
                *cell = fill as u8;
            }
        }
    }
    for fill in Fill::ALL {
        let path = runs(|cell| owner[cell] == fill as u8);
        if !path.is_empty() {
            let _ = write!(out, r#"<path d="{path}" {}/>"#, fill.style(false));
        }
    }
    let repaired = repaired.cells();
    let path = runs(|cell| repaired[cell]);
    if !path.is_empty() {
        let _ = write!(out, r#"<path d="{path}" fill="{REPAIRED_COLOUR}"/>"#);
    }
    whole
}

/// The covered cells as one path of row runs.
fn runs(covered: impl Fn(usize) -> bool) -> String {
    let mut path = String::new();
    for y in 0..GRID {
        let mut x = 0;
        while x < GRID {
            if !covered(y * GRID + x) {
                x += 1;
                continue;
            }
            let start = x;
            while x < GRID && covered(y * GRID + x) {
                x += 1;
            }
            let _ = write!(path, "M{start} {y}h{}v1h-{}z", x - start, x - start);
        }
    }
    path
}

/// Rings around the triangles worth finding (degenerate, zero UV area, repaired), which are
/// often too small to see: one per class in each 8-pixel cell at most, so their number is
/// bounded by the panel whatever the mesh.
fn finder_rings(out: &mut String, layout: &Layout, window: &Window) {
    let classes = [
        (
            TriangleMarks::DUPLICATE_POSITION | TriangleMarks::ZERO_AREA,
            Fill::Degenerate.swatch(),
        ),
        (TriangleMarks::ZERO_UV_AREA, Fill::ZeroUvArea.swatch()),
        (TriangleMarks::REPAIRED, REPAIRED_COLOUR),
    ];
    for (bits, colour) in classes {
        let mut seen = std::collections::HashSet::new();
        let mut path = String::new();
        for (t, marks) in layout.marks.triangles.iter().enumerate() {
            if !marks.has(bits) {
                continue;
            }
            let Some([a, b, c]) = corners(layout, window, t) else {
                continue;
            };
            let (x, y) = ((a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0);
            if seen.insert(((x / 8.0).floor() as i64, (y / 8.0).floor() as i64)) {
                let _ = write!(
                    path,
                    "M{:.1} {:.1}a7 7 0 1 0 14 0a7 7 0 1 0 -14 0",
                    x - 7.0,
                    y
                );
            }
        }
        if !path.is_empty() {
            let _ = write!(
                out,
                r#"<path d="{path}" fill="none" stroke="{colour}" stroke-width="1.5" opacity="0.9"/>"#
            );
        }
    }
}

/// A dot at every vertex where handedness flips, one per pixel at most.
fn flip_dots(out: &mut String, layout: &Layout, window: &Window) {
    let mut seen = std::collections::HashSet::new();
    let mut path = String::new();
    for &v in &layout.marks.flip_vertices {
        let Some(&uv) = layout.uvs.get(v as usize) else {
            continue;
        };
        if !(uv[0].is_finite() && uv[1].is_finite()) {
            continue;
        }
        let [x, y] = window.point(uv);
        if seen.insert((x.round() as i64, y.round() as i64)) {
            let _ = write!(path, "M{:.1} {:.1}h0", x, y);
        }
    }
    if !path.is_empty() {
        let _ = write!(
            out,
            r#"<path d="{path}" stroke="{FLIP_COLOUR}" stroke-width="4" stroke-linecap="round"/>"#
        );
    }
}

/// The legend: what each colour is and how many there are; returns its height.
fn legend(out: &mut String, layout: &Layout, window: &Window, top: f64, whole: bool) -> f64 {
    let marks = &layout.marks;
    let triangles = marks.triangles.len() as u64;
    let count = |fill: Fill| {
        marks
            .triangles
            .iter()
            .filter(|&&m| Fill::of(m) == fill)
            .count() as u64
    };
    let degenerate = |bits: u8| marks.count(bits);
    let mut rows: Vec<(String, String)> = vec![
        (
            Fill::Ordinary.swatch().into(),
            format!(
                "ordinary: {} of {} triangles",
                thousands(count(Fill::Ordinary)),
                thousands(triangles)
            ),
        ),
        (
            Fill::Mirrored.swatch().into(),
            format!(
                "mirrored UVs: {} (hatched; their tangents' w is -1: the texture is flipped there)",
                counted(marks.count(TriangleMarks::MIRRORED_UV), "triangle")
            ),
        ),
        (
            Fill::ZeroUvArea.swatch().into(),
            format!(
                "zero UV area: {} (outlined and ringed: no texture direction to follow)",
                counted(marks.count(TriangleMarks::ZERO_UV_AREA), "triangle")
            ),
        ),
        (
            Fill::Degenerate.swatch().into(),
            format!(
                "degenerate (ringed): {} with a duplicate position, {} with no area, {} non-finite",
                counted(degenerate(TriangleMarks::DUPLICATE_POSITION), "triangle"),
                degenerate(TriangleMarks::ZERO_AREA),
                degenerate(TriangleMarks::NON_FINITE)
            ),
        ),
        (
            REPAIRED_COLOUR.into(),
            format!(
                "repaired tangents: {} in {} (outlined and ringed)",
                counted(layout.repaired_corners, "corner"),
                counted(marks.count(TriangleMarks::REPAIRED), "triangle")
            ),
        ),
        (
            FLIP_COLOUR.into(),
            format!(
                "handedness flips: {} (dots; each split in two in the output)",
                counted(marks.flip_vertices.len() as u64, "vertex")
            ),
        ),
    ];
    if window.clips(layout) {
        rows.push((
            "#ffffff".into(),
            format!(
                "UVs beyond {} tiles from 0–1 are cut off",
                MAX_TILES_BEYOND as u32
            ),
        ));
    }
    if triangles as usize > VECTOR_TRIANGLES {
        rows.push((
            "#ffffff".into(),
            format!(
                "over {} triangles: drawn on a {GRID}×{GRID} grid, each pixel in the class lowest in this list among its triangles",
                thousands(VECTOR_TRIANGLES as u64)
            ),
        ));
    }
    if !whole {
        rows.push((
            "#ffffff".into(),
            "the triangles cover so much of the picture that the last were marked at their corners only".into(),
        ));
    }
    for (i, (colour, text)) in rows.iter().enumerate() {
        let y = top + i as f64 * LEGEND_ROW;
        let _ = write!(
            out,
            r##"<rect x="{MARGIN}" y="{y:.1}" width="14" height="14" fill="{colour}" stroke="#555555"/><text x="{:.1}" y="{:.1}" font-size="13" fill="#222222">{}</text>"##,
            MARGIN + 22.0,
            y + 12.0,
            escape(text)
        );
    }
    rows.len() as f64 * LEGEND_ROW
}

/// "1 triangle", "2 triangles"; "1 vertex", "2,000 vertices".
fn counted(n: u64, noun: &str) -> String {
    match (n, noun) {
        (1, _) => format!("1 {noun}"),
        (_, "vertex") => format!("{} vertices", thousands(n)),
        _ => format!("{} {noun}s", thousands(n)),
    }
}

/// `text` made safe inside an SVG element or attribute: markup escaped, control characters
/// dropped (file and mesh names come from the sender).
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if c.is_control() => {}
            c => out.push(c),
        }
    }
    out
}

/// At most `chars` characters of `text`, an ellipsis marking a cut.
fn shorten(text: &str, chars: usize) -> String {
    if text.chars().count() <= chars {
        return text.to_owned();
    }
    let mut short: String = text.chars().take(chars.saturating_sub(1)).collect();
    short.push('…');
    short
}

#[cfg(test)]
mod tests {
    use super::*;
    use tspace_tangent::Marks;

    fn layout(uvs: Vec<[f32; 2]>, marks: Vec<TriangleMarks>, flips: Vec<u32>) -> Layout {
        Layout {
            primitives: vec![crate::scene::layout::PrimitiveRef {
                mesh: 0,
                primitive: 0,
                mesh_name: Some("<Quad & \"friends\">".into()),
            }],
            texcoord: 0,
            indices: None,
            uvs,
            marks: Marks {
                triangles: marks,
                flip_vertices: flips,
            },
            repaired_corners: 0,
        }
    }

    #[test]
    fn names_are_escaped_and_every_class_has_a_path() {
        let uvs = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [0.2, 0.2],
            [0.4, 0.4],
            [0.6, 0.6],
        ];
        let marks = vec![
            TriangleMarks::default(),
            TriangleMarks::from_bits(TriangleMarks::MIRRORED_UV),
            TriangleMarks::from_bits(TriangleMarks::ZERO_UV_AREA),
        ];
        let svg = svg(
            &Subject { file: "a<b>.glb" },
            &[layout(uvs, marks, vec![1])],
        );
        assert!(svg.contains("a&lt;b&gt;.glb"), "{svg}");
        assert!(svg.contains("&lt;Quad &amp; &quot;friends&quot;&gt;"));
        assert!(!svg.contains("<Quad"));
        // One path per class present, ending in a triangle and carrying the class's style.
        for fill in [Fill::Ordinary, Fill::Mirrored, Fill::ZeroUvArea] {
            let path = format!("Z\" {}/>", fill.style(true));
            assert_eq!(svg.matches(&path).count(), 1, "{fill:?}");
        }
        assert!(!svg.contains(Fill::Degenerate.style(true)));
        assert!(svg.contains("mirrored UVs: 1 triangle ("));
        assert!(svg.contains("handedness flips: 1 vertex ("));
        let png = png(&svg).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }

    #[test]
    fn a_window_covers_the_tiles_the_uvs_reach_and_no_more_than_its_limit() {
        let w = Window::of(&layout(vec![[-0.5, 0.2], [2.5, 0.9]], vec![], vec![]));
        assert_eq!((w.u0, w.tiles_u, w.v0, w.tiles_v), (-1.0, 4.0, 0.0, 1.0));
        let far = layout(vec![[1e6, 0.0], [0.0, f32::NAN]], vec![], vec![]);
        let w = Window::of(&far);
        assert_eq!((w.u0, w.tiles_u), (0.0, 9.0));
        assert!(w.clips(&far));
    }

    #[test]
    fn huge_overlapping_triangles_cost_a_bounded_amount_of_work() {
        // Each triangle covers the whole tile: drawn whole, they would cost 1024 rows each.
        let triangles = 3 * (GRID_WORK as usize / GRID);
        let mut big = layout(
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            vec![TriangleMarks::default(); triangles],
            vec![],
        );
        big.indices = Some([0, 1, 2].repeat(triangles));
        let started = std::time::Instant::now();
        let svg = svg(&Subject { file: "big" }, &[big]);
        assert!(svg.contains("marked at their corners only"));
        assert!(started.elapsed() < std::time::Duration::from_secs(10));
    }

    #[test]
    fn thousands_are_separated() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1000), "1,000");
        assert_eq!(thousands(2_000_000), "2,000,000");
        assert_eq!(counted(1, "vertex"), "1 vertex");
        assert_eq!(counted(15452, "triangle"), "15,452 triangles");
    }

    #[test]
    fn the_grid_covers_a_triangle_and_keeps_thin_ones() {
        let mut coverage = Coverage::new();
        let mut budget = GRID_WORK;
        assert!(coverage.triangle([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0]], &mut budget));
        assert!(coverage.triangle(
            [[500.2, 500.2], [500.4, 500.3], [500.3, 500.4]],
            &mut budget
        ));
        let cells = coverage.cells();
        let covered = cells.iter().filter(|&&c| c).count();
        // Half of a 100 x 100 square, give or take its diagonal.
        assert!((4900..=5200).contains(&covered), "{covered}");
        assert!(
            cells[500 * GRID + 500],
            "a sub-pixel triangle keeps its pixel"
        );
        assert!(!cells[99 * GRID + 99]);
    }
}
