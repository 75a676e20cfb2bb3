//! The FMUs' icon, drawn here (no image file in the repository): a framed block with the backlash
//! characteristic (the parallelogram the output traces against the input), one port on the left per input
//! and one on the right per output, as the description declares them (build/docs.rs reads it). PNG through
//! the `png` crate.

/// Width and height of the icon, in pixels.
pub const SIZE: usize = 128;

type Rgb = [u8; 3];

const FRAME: Rgb = [0x1f, 0x3a, 0x68];
const FILL: Rgb = [0xf2, 0xf5, 0xfb];
const CURVE: Rgb = [0xc0, 0x39, 0x2b];
const AXES: Rgb = [0x99, 0x99, 0x99];

/// An RGBA image, transparent where nothing is drawn.
struct Canvas {
    px: Vec<u8>,
}

impl Canvas {
    fn new() -> Self {
        Self {
            px: vec![0; SIZE * SIZE * 4],
        }
    }

    /// Blends `c` over pixel (x, y) with coverage `alpha` in [0, 1].
    fn blend(&mut self, x: usize, y: usize, c: Rgb, alpha: f64) {
        if x >= SIZE || y >= SIZE || alpha <= 0.0 {
            return;
        }
        let i = 4 * (y * SIZE + x);
        let a = alpha.min(1.0);
        let old_a = f64::from(self.px[i + 3]) / 255.0;
        let new_a = a + old_a * (1.0 - a);
        for (p, &channel) in self.px[i..i + 3].iter_mut().zip(&c) {
            let old = f64::from(*p) * old_a * (1.0 - a);
            *p = ((f64::from(channel) * a + old) / new_a).round() as u8;
        }
        self.px[i + 3] = (new_a * 255.0).round() as u8;
    }

    /// Every pixel whose centre's signed distance `dist` to the shape is below half a pixel, anti-aliased.
    fn shape(&mut self, c: Rgb, dist: impl Fn(f64, f64) -> f64) {
        for y in 0..SIZE {
            for x in 0..SIZE {
                let d = dist(x as f64 + 0.5, y as f64 + 0.5);
                self.blend(x, y, c, 0.5 - d);
            }
        }
    }

    /// A line from a to b of width `w`.
    fn line(&mut self, a: (f64, f64), b: (f64, f64), w: f64, c: Rgb) {
        self.shape(c, |x, y| segment_distance((x, y), a, b) - w / 2.0);
    }

    /// A rectangle with rounded corners of radius r, filled with `fill` and framed `border` wide.
    fn rounded(&mut self, (x0, y0, x1, y1): (f64, f64, f64, f64), r: f64, fill: Rgb, border: f64) {
        let d = move |x: f64, y: f64| {
            let qx = (x - (x0 + x1) / 2.0).abs() - ((x1 - x0) / 2.0 - r);
            let qy = (y - (y0 + y1) / 2.0).abs() - ((y1 - y0) / 2.0 - r);
            qx.max(qy).min(0.0) + qx.max(0.0).hypot(qy.max(0.0)) - r
        };
        self.shape(FRAME, d);
        self.shape(fill, move |x, y| d(x, y) + border);
    }

    /// A port: a triangle pointing right with its tip at (x, y).
    fn port(&mut self, x: f64, y: f64, half: f64) {
        let (a, b, c) = (
            (x - half * 1.6, y - half),
            (x - half * 1.6, y + half),
            (x, y),
        );
        self.shape(FRAME, |px, py| {
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|&(p, q)| (q.0 - p.0) * (py - p.1) - (q.1 - p.1) * (px - p.0) <= 0.0);
            let edge = [(a, b), (b, c), (c, a)]
                .iter()
                .map(|&(p, q)| segment_distance((px, py), p, q))
                .fold(f64::INFINITY, f64::min);
            if inside { -edge } else { edge }
        });
    }
}

fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
}

/// Centres of n ports spread over the block's height.
fn port_rows(n: usize) -> impl Iterator<Item = f64> {
    let (top, bottom) = (24.0, SIZE as f64 - 24.0);
    (0..n).map(move |i| top + (bottom - top) * (i as f64 + 0.5) / n as f64)
}

/// The icon of an FMU with `inputs` inputs and `outputs` outputs, as PNG bytes.
pub fn png(inputs: usize, outputs: usize) -> Result<Vec<u8>, String> {
    let mut c = Canvas::new();
    let s = SIZE as f64;
    c.rounded((12.0, 8.0, s - 12.0, s - 8.0), 10.0, FILL, 3.0);
    let half = (40.0 / inputs.max(outputs).max(1) as f64).clamp(1.5, 7.0);
    for y in port_rows(inputs) {
        c.port(12.0, y, half);
    }
    for y in port_rows(outputs) {
        c.port(s - 1.0, y, half);
    }
    // Axes through the centre, then the backlash: up the right border, across, down the left, across.
    let (cx, cy) = (s / 2.0, s / 2.0);
    c.line((28.0, cy), (s - 28.0, cy), 1.5, AXES);
    c.line((cx, 24.0), (cx, s - 24.0), 1.5, AXES);
    let (gap, rise) = (14.0, 30.0);
    let corners = [
        (cx - gap - rise, cy + rise),
        (cx + gap - rise, cy + rise),
        (cx + gap + rise, cy - rise),
        (cx - gap + rise, cy - rise),
    ];
    for k in 0..4 {
        c.line(corners[k], corners[(k + 1) % 4], 4.0, CURVE);
    }
    encode(&c.px)
}

fn encode(rgba: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, SIZE as u32, SIZE as u32);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc
        .write_header()
        .map_err(|e| format!("writing the icon: {e}"))?;
    w.write_image_data(rgba)
        .map_err(|e| format!("writing the icon: {e}"))?;
    w.finish().map_err(|e| format!("writing the icon: {e}"))?;
    Ok(out)
}
