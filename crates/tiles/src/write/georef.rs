//! Where an exported tileset sits on the globe. A store whose CRS names an EPSG code that the
//! `crs-definitions` table knows is placed in ECEF: the root transform is the first-order
//! (Jacobian) map of the projection at the data's centre, from local metres (x east-ish, y
//! north-ish, z up) to ECEF, so grid convergence, scale factor and units are in it. Points away
//! from the centre deviate from their exact projection by the second-order terms (Earth
//! curvature: about d²/2R, 8 cm at 1 km). Heights are taken as ellipsoidal (no geoid model).
//! Any other store is written in its own coordinates, with the root transform a translation.

use crate::transform::Transform;
use crate::volume::geodetic_to_ecef;
use pointlet_core::crs::{Crs, CrsId};
use proj4rs::Proj;

/// How the tileset's local frame relates to the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Georeference {
    /// Local tile coordinates → tileset world (ECEF, or the store's own coordinates).
    pub root_transform: Transform,
    /// Metres per store unit on x, y and z (1 for a local tileset: its units are the store's).
    pub metres_per_unit: [f64; 3],
    /// Store coordinates of the local frame's origin (the data's centre).
    pub origin: [f64; 3],
    /// `Some(EPSG code)` when placed in ECEF.
    pub epsg: Option<u32>,
    /// One line for stderr and `asset.extras`: what was done and why.
    pub note: String,
}

/// A projected or geographic CRS by EPSG code, able to give WGS 84 longitude and latitude.
pub struct Projection {
    source: Proj,
    wgs84: Proj,
    code: u32,
    /// Metres per horizontal unit of the CRS.
    pub horizontal_unit: f64,
    geographic: bool,
}

impl Projection {
    /// The projection of EPSG `code`; the error says why there is none.
    pub fn from_epsg(code: u32) -> Result<Projection, String> {
        let short = u16::try_from(code)
            .map_err(|_| format!("EPSG:{code} is not in the built-in EPSG table"))?;
        let source = Proj::from_epsg_code(short)
            .map_err(|e| format!("EPSG:{code}: no usable projection definition ({e})"))?;
        let wgs84 = Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs")
            .map_err(|e| format!("WGS 84: {e}"))?;
        let geographic = source.is_latlong();
        Ok(Projection {
            horizontal_unit: if geographic { 1.0 } else { source.to_meter() },
            source,
            wgs84,
            code,
            geographic,
        })
    }

    pub fn code(&self) -> u32 {
        self.code
    }

    /// WGS 84 longitude and latitude (radians) of CRS coordinates `x`, `y`.
    pub fn to_lon_lat(&self, x: f64, y: f64) -> Result<(f64, f64), String> {
        let (x, y) = if self.geographic {
            (x.to_radians(), y.to_radians())
        } else {
            (x, y)
        };
        let (lon, lat, _) = proj4rs::adaptors::transform_xyz(&self.source, &self.wgs84, x, y, 0.0)
            .map_err(|e| format!("EPSG:{}: cannot project ({x}, {y}): {e}", self.code))?;
        if lon.is_finite() && lat.is_finite() {
            Ok((lon, lat))
        } else {
            Err(format!(
                "EPSG:{}: ({x}, {y}) projects to no finite place",
                self.code
            ))
        }
    }

    /// ECEF of CRS coordinates `p` (x, y in CRS units; z in metres above the ellipsoid).
    pub fn to_ecef(&self, x: f64, y: f64, height_m: f64) -> Result<[f64; 3], String> {
        let (lon, lat) = self.to_lon_lat(x, y)?;
        Ok(geodetic_to_ecef(lon, lat, height_m))
    }
}

/// Metres per unit of the vertical CRS codes LAS files commonly carry; `None` when unknown.
fn vertical_unit(v: &CrsId) -> Option<f64> {
    const US_FOOT: f64 = 1200.0 / 3937.0;
    match v {
        // NAVD88 height (ftUS), NGVD29 height (ftUS).
        CrsId::Epsg(6360 | 5702) => Some(US_FOOT),
        // NAVD88 height (ft), international foot.
        CrsId::Epsg(8228) => Some(0.3048),
        // NAVD88, EGM96/EGM2008, DHHN, NN54 and others in metres.
        CrsId::Epsg(5703 | 5773 | 3855 | 5783 | 5776 | 5714 | 5701 | 7837) => Some(1.0),
        _ => None,
    }
}

/// A local tileset of a store with bounds `bounds`: its own coordinates, `why` said.
pub fn local_frame(bounds: &pointlet_core::Aabb, why: &str) -> Georeference {
    let origin = bounds.center();
    Georeference {
        root_transform: Transform::from_translation(origin),
        metres_per_unit: [1.0; 3],
        origin,
        epsg: None,
        note: format!(
            "{why}: the tileset is local (the store's own coordinates, not placed on the globe)"
        ),
    }
}

/// The georeference of a store with CRS records `crs` and bounds `bounds` (store units).
pub fn georeference(crs: Option<&Crs>, bounds: &pointlet_core::Aabb) -> Georeference {
    let local = |why: String| local_frame(bounds, &why);
    let origin = bounds.center();
    let Some(crs) = crs else {
        return local("the store has no CRS".into());
    };
    let code = match &crs.horizontal {
        Some(CrsId::Epsg(code)) => *code,
        Some(other) => return local(format!("the store's CRS {other} has no EPSG code")),
        None => return local(format!("the store's CRS ({crs}) has no horizontal part")),
    };
    let projection = match Projection::from_epsg(code) {
        Ok(p) => p,
        Err(why) => return local(why),
    };
    if projection.geographic {
        return local(format!(
            "EPSG:{code} is geographic (degrees): only projected CRSs are placed"
        ));
    }
    let h = projection.horizontal_unit;
    let (v, v_note) = match crs.vertical.as_ref().map(|v| (v, vertical_unit(v))) {
        Some((_, Some(unit))) => (unit, String::new()),
        Some((id, None)) => (
            h,
            format!("; vertical CRS {id} unknown, heights taken in the horizontal unit"),
        ),
        None => (h, String::new()),
    };
    match jacobian_frame(&projection, origin, [h, h, v]) {
        Ok(root_transform) => Georeference {
            root_transform,
            metres_per_unit: [h, h, v],
            origin,
            epsg: Some(code),
            note: format!(
                "placed in ECEF from EPSG:{code} ({h} m per horizontal unit, {v} m per vertical unit{v_note}); heights taken as ellipsoidal"
            ),
        },
        Err(why) => local(why),
    }
}

/// Local metres around `origin` (store units) → ECEF, linearised at `origin` by central
/// differences over `step` metres.
fn jacobian_frame(
    projection: &Projection,
    origin: [f64; 3],
    metres_per_unit: [f64; 3],
) -> Result<Transform, String> {
    const STEP_M: f64 = 10.0;
    let at = |dx: f64, dy: f64, dz: f64| {
        projection.to_ecef(
            origin[0] + dx / metres_per_unit[0],
            origin[1] + dy / metres_per_unit[1],
            origin[2] * metres_per_unit[2] + dz,
        )
    };
    let centre = at(0.0, 0.0, 0.0)?;
    let mut m = Transform::IDENTITY;
    for (axis, d) in [[STEP_M, 0.0, 0.0], [0.0, STEP_M, 0.0], [0.0, 0.0, STEP_M]]
        .iter()
        .enumerate()
    {
        let plus = at(d[0], d[1], d[2])?;
        let minus = at(-d[0], -d[1], -d[2])?;
        for r in 0..3 {
            m.0[axis * 4 + r] = (plus[r] - minus[r]) / (2.0 * STEP_M);
        }
    }
    m.0[12..15].copy_from_slice(&centre);
    match m.defect() {
        Some(defect) => Err(format!(
            "EPSG:{}: the local frame {defect}",
            projection.code
        )),
        None => Ok(m),
    }
}
