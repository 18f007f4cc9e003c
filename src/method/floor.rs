//! Distance from a camera's altitude over a flat seabed (METHOD §13.7):
//! the range along each pixel's ray from a pinhole camera behind a flat or
//! dome port, looking down with a pitch and a roll, to the plane at the
//! altitude below it.

/// Refractive index of sea water for visible light, relative to air (the
/// flat port's bending, METHOD §13.7).
pub const WATER_INDEX: f64 = 1.333;

/// The largest field of view accepted, in degrees: a pinhole camera's
/// horizontal angle stays well below 180.
pub const MAX_FOV: f64 = 170.0;

/// The steepest pitch or roll accepted, in degrees: beyond it the camera
/// looks above the horizon in the middle of the photo.
pub const MAX_TILT: f64 = 89.0;

/// How the housing's window bends the rays (METHOD §13.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Port {
    /// a flat window perpendicular to the optical axis: Snell's law narrows
    /// the field of view in water
    Flat,
    /// a dome centred on the lens: rays cross it unbent
    Dome,
}

impl Port {
    /// The name the options and the sidecar use.
    pub fn name(self) -> &'static str {
        match self {
            Port::Flat => "flat",
            Port::Dome => "dome",
        }
    }

    /// The port of a name ("flat" or "dome").
    pub fn parse(s: &str) -> Option<Port> {
        match s {
            "flat" => Some(Port::Flat),
            "dome" => Some(Port::Dome),
            _ => None,
        }
    }
}

/// A downward camera over a flat seabed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Floor {
    /// metres from the camera down to the seabed
    pub altitude: f64,
    /// the lens's horizontal field of view in air across the photo's width, degrees
    pub fov: f64,
    /// degrees, positive nose up (the camera then looks down and forward: the photo's top)
    pub pitch: f64,
    /// degrees, positive starboard down (the camera then looks down and to port: the photo's left)
    pub roll: f64,
    /// the housing's window
    pub port: Port,
}

impl Floor {
    /// Checks the values a file or an option may give (finite, altitude in
    /// (0, `MAX_DISTANCE`], fov in (0, [`MAX_FOV`]], tilts within [`MAX_TILT`]).
    pub fn check(&self) -> Result<(), String> {
        let max = f64::from(crate::method::distance::MAX_DISTANCE);
        if !(self.altitude.is_finite() && self.altitude > 0.0 && self.altitude <= max) {
            return Err(format!("altitude {} m is not in (0, {max}]", crate::error::shown_number(self.altitude)));
        }
        check_fov(self.fov)?;
        for (name, v) in [("pitch", self.pitch), ("roll", self.roll)] {
            if !(v.is_finite() && v.abs() <= MAX_TILT) {
                return Err(format!("{name} {} degrees is not within +-{MAX_TILT}", crate::error::shown_number(v)));
            }
        }
        Ok(())
    }

    /// The horizontal field of view in water across the photo's width,
    /// degrees: the air angle behind a dome, narrowed by Snell's law at the
    /// edge of the photo behind a flat port.
    pub fn fov_in_water(&self) -> f64 {
        fov_in_water(self.fov, self.port)
    }

    /// The range in metres along the ray of each pixel of an `h` x `w`
    /// photo to the seabed, row-major; NaN where the ray does not meet it
    /// (at or above the horizon) or meets it beyond `MAX_DISTANCE`.
    /// METHOD §13.7. Call [`Floor::check`] first: unchecked values give NaN.
    pub fn distances(&self, h: usize, w: usize) -> Vec<f32> {
        let (sp, cp) = self.pitch.to_radians().sin_cos();
        let (sr, cr) = self.roll.to_radians().sin_cos();
        let max = f64::from(crate::method::distance::MAX_DISTANCE);
        let mut out = Vec::with_capacity(h.saturating_mul(w));
        let rays = Rays::new(self.fov, self.port, h, w);
        for r in 0..h {
            for c in 0..w {
                let (dx, dy, dz) = rays.at(r, c);
                // camera to body: image top forward, image right starboard, axis down
                let (bx, by, bz) = (-dy, dx, dz);
                // roll about X, then pitch about Y: only the down component is needed
                let rz = by * sr + bz * cr;
                let wz = -bx * sp + rz * cp;
                let range = self.altitude / wz;
                out.push(if wz > 0.0 && range <= max { range as f32 } else { f32::NAN });
            }
        }
        out
    }
}

/// Checks a lens's horizontal field of view in air, degrees: finite, in
/// (0, [`MAX_FOV`]] (an option, the EXIF or a manifest may give any value).
pub fn check_fov(fov: f64) -> Result<(), String> {
    if fov.is_finite() && fov > 0.0 && fov <= MAX_FOV {
        Ok(())
    } else {
        Err(format!("field of view {} degrees is not in (0, {MAX_FOV}]", crate::error::shown_number(fov)))
    }
}

/// The horizontal field of view in water, degrees, of a lens of `fov`
/// degrees in air behind `port`: the air angle behind a dome, narrowed by
/// Snell's law at the edge of the photo behind a flat window.
pub fn fov_in_water(fov: f64, port: Port) -> f64 {
    match port {
        Port::Dome => fov,
        Port::Flat => 2.0 * ((fov.to_radians() / 2.0).sin() / WATER_INDEX).asin().to_degrees(),
    }
}

/// The rays in water of the pixels of an `h` x `w` photo from a pinhole
/// camera whose horizontal field of view in air across the width is `fov`
/// degrees, behind `port` (METHOD §13.7): unit vectors in the camera's
/// frame (x right, y down, z along the optical axis).
struct Rays {
    f: f64,
    port: Port,
    h: usize,
    w: usize,
}

impl Rays {
    fn new(fov: f64, port: Port, h: usize, w: usize) -> Self {
        Self { f: (w as f64 / 2.0) / (fov.to_radians() / 2.0).tan(), port, h, w }
    }

    /// The ray of the pixel in row `r`, column `c` (through its centre).
    fn at(&self, r: usize, c: usize) -> (f64, f64, f64) {
        let v = r as f64 + 0.5 - self.h as f64 / 2.0;
        let u = c as f64 + 0.5 - self.w as f64 / 2.0;
        let n = (u * u + v * v + self.f * self.f).sqrt();
        let (mut dx, mut dy, mut dz) = (u / n, v / n, self.f / n);
        if self.port == Port::Flat {
            // Snell's law at a window perpendicular to the axis
            dx /= WATER_INDEX;
            dy /= WATER_INDEX;
            dz = (1.0 - dx * dx - dy * dy).max(0.0).sqrt();
        }
        (dx, dy, dz)
    }
}

/// A depth map (distance along the camera's optical axis, as photogrammetry
/// exports it: Metashape, COLMAP) of an `h` x `w` photo turned in place into
/// the range along each pixel's ray, which the model needs (METHOD §13.7,
/// "Depth along the axis"): each value divided by the cosine of its ray's
/// angle to the axis in water. `fov` is the horizontal field of view in air
/// across the width, degrees ([`check_fov`]: the map is left as it is when
/// out of range); NaN stays NaN.
pub fn depth_to_range(depth: &mut [f32], h: usize, w: usize, fov: f64, port: Port) -> Result<(), String> {
    check_fov(fov)?;
    let rays = Rays::new(fov, port, h, w);
    for (i, d) in depth.iter_mut().enumerate().take(h.saturating_mul(w)) {
        let (_, _, dz) = rays.at(i / w.max(1), i % w.max(1));
        *d = (f64::from(*d) / dz) as f32;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_along_the_axis_becomes_the_range_along_each_ray() {
        // 1 x 3 photo, 90 degrees across: the outer pixels' centres are at
        // u = +-1 of f = 1.5 (tan 45 = 1.5 / 1.5), so their rays make
        // atan(1 / 1.5) with the axis behind a dome; the middle one is on it
        let (h, w) = (1, 3);
        let mut d = vec![2.0f32, 2.0, f32::NAN];
        depth_to_range(&mut d, h, w, 90.0, Port::Dome).unwrap();
        let cos = (1.0f64 / 1.5).atan().cos();
        assert!((f64::from(d[0]) - 2.0 / cos).abs() < 1e-6, "{}", d[0]);
        assert_eq!(d[1], 2.0);
        assert!(d[2].is_nan());
        // behind a flat port the ray in water is bent toward the axis:
        // sin(in water) = sin(in air) / 1.333
        let mut d = vec![2.0f32, 2.0, 2.0];
        depth_to_range(&mut d, h, w, 90.0, Port::Flat).unwrap();
        let air = (1.0f64 / 1.5).atan();
        let water = (air.sin() / WATER_INDEX).asin();
        assert!((f64::from(d[2]) - 2.0 / water.cos()).abs() < 1e-6, "{}", d[2]);
        assert!(d[0] == d[2] && d[1] == 2.0 && d[0] < (2.0 / cos) as f32);
        // a field of view out of range leaves the map as it was
        for fov in [0.0, 171.0, f64::NAN] {
            let e = depth_to_range(&mut d, h, w, fov, Port::Flat).unwrap_err();
            assert!(e.contains("is not in (0, 170]"), "{e}");
        }
        assert_eq!(d[1], 2.0);
    }

    fn floor(altitude: f64, fov: f64, pitch: f64, roll: f64, port: Port) -> Floor {
        Floor { altitude, fov, pitch, roll, port }
    }

    fn at(z: &[f32], w: usize, r: usize, c: usize) -> f64 {
        f64::from(z[r * w + c])
    }

    #[test]
    fn level_camera_sees_the_altitude_below_and_the_edge_at_half_the_fov() {
        // odd size: the middle pixel's ray is the optical axis
        let (h, w) = (5, 101);
        let z = floor(3.0, 90.0, 0.0, 0.0, Port::Dome).distances(h, w);
        assert!((at(&z, w, 2, 50) - 3.0).abs() < 1e-6);
        // the outer edge of the last column is at 45 degrees: its centre at atan(49.5/50.5... of f = 50.5)
        let f = 50.5_f64;
        let expect = 3.0 * ((50.0_f64 / f).powi(2) + 1.0).sqrt();
        assert!((at(&z, w, 2, 100) - expect).abs() < 1e-5, "{} {expect}", at(&z, w, 2, 100));
        // symmetric left and right, up and down
        assert!((at(&z, w, 2, 0) - at(&z, w, 2, 100)).abs() < 1e-6);
        assert!((at(&z, w, 0, 50) - at(&z, w, 4, 50)).abs() < 1e-6);
    }

    #[test]
    fn a_flat_port_narrows_the_angle_by_snells_law() {
        let (h, w) = (1, 201);
        let air = floor(2.0, 80.0, 0.0, 0.0, Port::Dome);
        let flat = Floor { port: Port::Flat, ..air };
        let (za, zf) = (air.distances(h, w), flat.distances(h, w));
        // last column: in air at angle a with tan a = u/f; in water sin b = sin a / 1.333
        let f = 100.5 / 40f64.to_radians().tan();
        let a = (100.0 / f).atan();
        let b = (a.sin() / 1.333).asin();
        assert!((at(&za, w, 0, 200) - 2.0 / a.cos()).abs() < 1e-5);
        assert!((at(&zf, w, 0, 200) - 2.0 / b.cos()).abs() < 1e-5);
        assert!(at(&zf, w, 0, 200) < at(&za, w, 0, 200));
        // 80 degrees in air: 2 asin(0.642788 / 1.333) = 2 asin(0.482211) = 57.66 degrees in water
        assert!((flat.fov_in_water() - 57.66).abs() < 0.005, "{}", flat.fov_in_water());
        assert_eq!(air.fov_in_water(), 80.0);
    }

    #[test]
    fn pitch_nose_up_looks_forward_and_roll_starboard_down_looks_to_port() {
        let (h, w) = (101, 101);
        // pitch: the axis is at the pitch angle from the vertical, range h / cos
        let p = floor(2.0, 60.0, 20.0, 0.0, Port::Dome).distances(h, w);
        assert!((at(&p, w, 50, 50) - 2.0 / 20f64.to_radians().cos()).abs() < 1e-5);
        // nose up: the photo's top (forward) looks further than its bottom
        assert!(at(&p, w, 0, 50) > at(&p, w, 100, 50));
        assert!((at(&p, w, 50, 0) - at(&p, w, 50, 100)).abs() < 1e-6);
        // roll starboard down: the camera looks to port, the photo's left is far
        let r = floor(2.0, 60.0, 0.0, 15.0, Port::Dome).distances(h, w);
        assert!((at(&r, w, 50, 50) - 2.0 / 15f64.to_radians().cos()).abs() < 1e-5);
        assert!(at(&r, w, 50, 0) > at(&r, w, 50, 100));
        // both: the axis's down component is cos(pitch) cos(roll)
        let b = floor(2.0, 60.0, 10.0, -12.0, Port::Flat).distances(h, w);
        let want = 2.0 / (10f64.to_radians().cos() * 12f64.to_radians().cos());
        assert!((at(&b, w, 50, 50) - want).abs() < 1e-5);
    }

    #[test]
    fn rays_at_or_above_the_horizon_have_no_distance() {
        // pitched 80 degrees with a 60 degree view: the top rows look above the horizon
        let z = floor(2.0, 60.0, 80.0, 0.0, Port::Dome).distances(61, 61);
        assert!(z[0].is_nan());
        assert!(z[60 * 61 + 30].is_finite());
        // from 1000 m everything off-axis is beyond the limit of a known distance
        let far = floor(1000.0, 60.0, 0.0, 0.0, Port::Dome).distances(3, 3);
        assert!(far[0].is_nan() && far[4].is_finite());
    }

    #[test]
    fn values_out_of_range_are_refused_by_name() {
        let ok = floor(2.0, 70.0, 5.0, -5.0, Port::Flat);
        assert!(ok.check().is_ok());
        for (bad, word) in [
            (Floor { altitude: 0.0, ..ok }, "altitude"),
            (Floor { altitude: f64::NAN, ..ok }, "altitude"),
            (Floor { altitude: 1e5, ..ok }, "altitude"),
            (Floor { fov: 180.0, ..ok }, "field of view"),
            (Floor { fov: -3.0, ..ok }, "field of view"),
            (Floor { pitch: 95.0, ..ok }, "pitch"),
            (Floor { roll: f64::INFINITY, ..ok }, "roll"),
        ] {
            let e = bad.check().unwrap_err();
            assert!(e.contains(word), "{e}");
        }
    }
}
