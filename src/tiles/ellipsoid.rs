//! The WGS84 ellipsoid, as a quantized-mesh header needs it: a point's Earth-centred (ECEF)
//! position, a bounding sphere, and the horizon occlusion point by which a client skips
//! tiles behind the Earth's limb (Cesium's `EllipsoidalOccluder`).
//!
//! Trigonometry goes through `libm`, not the platform's maths library, so that a tile's
//! header is the same bytes on every machine.

/// WGS84's equatorial radius, metres.
pub const SEMI_MAJOR_AXIS: f64 = 6_378_137.0;

/// WGS84's polar radius, metres.
pub const SEMI_MINOR_AXIS: f64 = 6_356_752.314_245_179;

/// WGS84's first eccentricity squared, 1 − b²/a².
pub(super) const E2: f64 = 0.006_694_379_990_141_317;

/// The largest magnitude a horizon occlusion point is given, in ellipsoid radii: a tile
/// that reaches around the limb (a level-0 tile spans a hemisphere) has no finite point
/// that hides it, and this one is visible from every camera on its side of the Earth.
const FAR: f64 = 1e6;

/// The ECEF position of longitude `lon`, latitude `lat` (degrees) at `height` metres above
/// the ellipsoid.
pub fn to_ecef(lon: f64, lat: f64, height: f64) -> [f64; 3] {
    let (lon, lat) = (lon.to_radians(), lat.to_radians());
    let (sin_lat, cos_lat) = (libm::sin(lat), libm::cos(lat));
    // The radius of curvature in the prime vertical.
    let n = SEMI_MAJOR_AXIS / libm::sqrt(1.0 - E2 * sin_lat * sin_lat);
    [
        (n + height) * cos_lat * libm::cos(lon),
        (n + height) * cos_lat * libm::sin(lon),
        (n * (1.0 - E2) + height) * sin_lat,
    ]
}

/// The smallest sphere centred on the middle of `points`' bounding box that holds them all:
/// (centre, radius).
pub fn bounding_sphere(points: &[[f64; 3]]) -> ([f64; 3], f64) {
    let Some(&first) = points.first() else { return ([0.0; 3], 0.0) };
    let (lo, hi) = points.iter().fold((first, first), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    let centre: [f64; 3] = std::array::from_fn(|k| lo[k] / 2.0 + hi[k] / 2.0);
    let radius = points.iter().map(|p| distance(p, &centre)).fold(0.0, f64::max);
    (centre, radius)
}

/// The horizon occlusion point of `points` (ECEF) in the ellipsoid's scaled space, on the ray
/// towards `towards` (the bounding sphere's centre): a client that cannot see it cannot see
/// any of the points.
pub fn horizon_occlusion_point(towards: &[f64; 3], points: &[[f64; 3]]) -> [f64; 3] {
    let direction = scaled(towards);
    let length = norm(&direction);
    if length == 0.0 {
        return [0.0; 3];
    }
    let direction = direction.map(|c| c / length);
    let magnitude = points.iter().map(|p| magnitude(p, &direction)).fold(0.0, f64::max).clamp(1.0, FAR);
    direction.map(|c| c * magnitude)
}

/// How far along `direction` (scaled space, unit) the occlusion point must lie for `point`
/// to be hidden only when the point is (Cesium's `computeMagnitude`); [`FAR`] when no
/// distance is enough. A point below the ellipsoid counts as on it.
fn magnitude(point: &[f64; 3], direction: &[f64; 3]) -> f64 {
    let p = scaled(point);
    let length = norm(&p).max(1e-300);
    let unit = p.map(|c| c / length);
    let length = length.max(1.0);
    let cos_alpha = dot(&unit, direction);
    let sin_alpha = norm(&cross(&unit, direction));
    let cos_beta = 1.0 / length;
    let sin_beta = libm::sqrt(length * length - 1.0) * cos_beta;
    let denominator = cos_alpha * cos_beta - sin_alpha * sin_beta;
    if denominator > 1.0 / FAR { 1.0 / denominator } else { FAR }
}

/// A point in the ellipsoid's scaled space, where it is the unit sphere.
fn scaled(p: &[f64; 3]) -> [f64; 3] {
    [p[0] / SEMI_MAJOR_AXIS, p[1] / SEMI_MAJOR_AXIS, p[2] / SEMI_MINOR_AXIS]
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn norm(a: &[f64; 3]) -> f64 {
    libm::sqrt(dot(a, a))
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    norm(&[a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_points_land_where_wgs84_puts_them() {
        assert_eq!(to_ecef(0.0, 0.0, 0.0), [SEMI_MAJOR_AXIS, 0.0, 0.0]);
        let pole = to_ecef(0.0, 90.0, 0.0);
        assert!(pole[0].abs() < 1e-6 && (pole[2] - SEMI_MINOR_AXIS).abs() < 1e-6, "{pole:?}");
        let east = to_ecef(90.0, 0.0, 100.0);
        assert!(east[0].abs() < 1e-6 && (east[1] - SEMI_MAJOR_AXIS - 100.0).abs() < 1e-6);
        // E2 is 1 − b²/a².
        assert!((E2 - (1.0 - (SEMI_MINOR_AXIS / SEMI_MAJOR_AXIS).powi(2))).abs() < 1e-15);
    }

    #[test]
    fn the_sphere_holds_every_point() {
        let points: Vec<_> =
            (0..50).map(|k| to_ecef(10.0 + f64::from(k) * 0.01, 45.0, f64::from(k % 7) * 100.0)).collect();
        let (centre, radius) = bounding_sphere(&points);
        assert!(points.iter().all(|p| distance(p, &centre) <= radius));
        // Half of 0.49° of longitude at 45°N is about 19.2 km.
        assert!(radius > 19_000.0 && radius < 19_500.0, "{radius}");
    }

    /// Whether a camera at `camera` (ECEF) sees scaled-space point `occludee` past the limb,
    /// as Cesium's `EllipsoidalOccluder.isScaledSpacePointVisible` decides.
    fn visible(camera: &[f64; 3], occludee: &[f64; 3]) -> bool {
        let cv = scaled(camera);
        let vh = dot(&cv, &cv) - 1.0;
        let vt = [occludee[0] - cv[0], occludee[1] - cv[1], occludee[2] - cv[2]];
        let vt_dot_vc = -dot(&vt, &cv);
        !(vt_dot_vc > vh && vt_dot_vc * vt_dot_vc / dot(&vt, &vt) > vh)
    }

    #[test]
    fn a_tile_is_culled_only_when_none_of_its_points_is_in_sight() {
        // A tile of a degree around (10°E, 45°N) with a 2 km mountain.
        let points: Vec<_> = (0..=10)
            .flat_map(|i| (0..=10).map(move |j| (10.0 + f64::from(i) / 10.0, 45.0 + f64::from(j) / 10.0)))
            .map(|(lon, lat)| to_ecef(lon, lat, if lon == 10.5 && lat == 45.5 { 2000.0 } else { 0.0 }))
            .collect();
        let (centre, _) = bounding_sphere(&points);
        let hop = horizon_occlusion_point(&centre, &points);
        // Cameras all around the globe at 1000 km: whenever a point would be in sight
        // (above the camera's horizon), the occlusion point must be visible too.
        for lon in (-180..180).step_by(5) {
            for lat in (-85..=85).step_by(5) {
                let camera = to_ecef(f64::from(lon), f64::from(lat), 1_000_000.0);
                let any_in_sight = points.iter().any(|p| visible(&camera, &scaled(p)));
                if any_in_sight {
                    assert!(visible(&camera, &hop), "culled from ({lon}, {lat}) though a point is in sight");
                }
            }
        }
        // And it is culled from the far side.
        assert!(!visible(&to_ecef(-170.0, -45.0, 1_000_000.0), &hop));
    }

    #[test]
    fn a_hemisphere_gets_a_far_point_rather_than_none() {
        let points: Vec<_> = [(-180.0, 0.0), (0.0, 0.0), (-90.0, 89.0), (-90.0, -89.0), (-90.0, 0.0)]
            .map(|(lon, lat)| to_ecef(lon, lat, 100.0))
            .to_vec();
        let (centre, _) = bounding_sphere(&points);
        let hop = horizon_occlusion_point(&centre, &points);
        assert!((norm(&hop) - FAR).abs() < 1.0, "{hop:?}");
        assert!(visible(&to_ecef(-90.0, 0.0, 500_000.0), &hop));
    }
}
