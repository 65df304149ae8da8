//! Per-vertex normals for the `octvertexnormals` extension, from the DEM around each vertex
//! rather than from a tile's triangles: a function of the position and the level alone, so
//! that two tiles sharing a side give its vertices the same normals and the light does not
//! show the seam.

use super::ellipsoid::{E2, SEMI_MAJOR_AXIS};
use super::mesher::height;
use super::view::View;
use crate::geom::Point;

/// The unit normal, in Earth-centred (ECEF) axes, of the DEM's surface at each of `vertices`
/// (longitude, latitude in degrees, height): the slope from central differences `step` degrees
/// either side, in metres on the WGS84 ellipsoid at that latitude.
pub fn normals(dem: &View<'_>, vertices: &[[f64; 3]], step: f64) -> Vec<[f64; 3]> {
    vertices
        .iter()
        .map(|&[lon, lat, _]| {
            let height = |dlon: f64, dlat: f64| height(dem, Point::new(lon + dlon, lat + dlat));
            let (phi, lambda) = (lat.to_radians(), lon.to_radians());
            let (sin_phi, cos_phi) = (libm::sin(phi), libm::cos(phi));
            let (sin_lambda, cos_lambda) = (libm::sin(lambda), libm::cos(lambda));
            let w = libm::sqrt(1.0 - E2 * sin_phi * sin_phi);
            // Metres a degree east (the prime vertical's radius) and north (the meridian's).
            let east_m = (SEMI_MAJOR_AXIS / w) * cos_phi * std::f64::consts::PI / 180.0;
            let north_m = SEMI_MAJOR_AXIS * (1.0 - E2) / (w * w * w) * std::f64::consts::PI / 180.0;
            // At a pole a degree east is no distance: only the north slope is defined.
            let dz_dx = if east_m > 1e-6 {
                (height(step, 0.0) - height(-step, 0.0)) / (2.0 * step * east_m)
            } else {
                0.0
            };
            let dz_dy = (height(0.0, step) - height(0.0, -step)) / (2.0 * step * north_m);
            // In east, north, up; then to ECEF through the geodetic frame.
            let (e, n, u) = (-dz_dx, -dz_dy, 1.0);
            let length = libm::sqrt(e * e + n * n + u * u);
            let (e, n, u) = (e / length, n / length, u / length);
            let east = [-sin_lambda, cos_lambda, 0.0];
            let north = [-sin_phi * cos_lambda, -sin_phi * sin_lambda, cos_phi];
            let up = [cos_phi * cos_lambda, cos_phi * sin_lambda, sin_phi];
            std::array::from_fn(|k| e * east[k] + n * north[k] + u * up[k])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Rect;
    use crate::source::Grid;
    use crate::tiles::ellipsoid::to_ecef;

    fn plane(slope_east: f64) -> Grid {
        // Heights rising `slope_east` metres a degree of longitude, over 10°–11°E, 45°–46°N.
        let values =
            (0..101).flat_map(|_| (0..101).map(move |i| 100.0 + slope_east * f64::from(i) / 100.0)).collect();
        Grid::new(101, 101, values).unwrap().with_domain(Rect::new(10.0, 11.0, 45.0, 46.0).unwrap())
    }

    #[test]
    fn flat_ground_faces_straight_up_from_the_ellipsoid() {
        let n = normals(&View::whole(&plane(0.0)), &[[10.5, 45.5, 100.0]], 0.01)[0];
        // The geodetic up: the direction from a point just below to the point.
        let (a, b) = (to_ecef(10.5, 45.5, 0.0), to_ecef(10.5, 45.5, 1.0));
        let up: Vec<f64> = (0..3).map(|k| b[k] - a[k]).collect();
        assert!((0..3).all(|k| (n[k] - up[k]).abs() < 1e-9), "{n:?} vs {up:?}");
        assert!(((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_slope_rising_east_tilts_the_normal_west_by_its_angle() {
        // 1000 m a degree of longitude at 45.5°N, where a degree is about 78 km: atan(1000/78000).
        let n = normals(&View::whole(&plane(1000.0)), &[[10.5, 45.5, 600.0]], 0.01)[0];
        let east = [-(10.5f64.to_radians()).sin(), (10.5f64.to_radians()).cos(), 0.0];
        let along: f64 = (0..3).map(|k| n[k] * east[k]).sum();
        let metres_a_degree = to_ecef(10.0, 45.5, 0.0)
            .iter()
            .zip(to_ecef(11.0, 45.5, 0.0))
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let want = -(1000.0 / metres_a_degree).atan().sin();
        assert!((along - want).abs() < 1e-4, "{along} vs {want}");
    }
}
