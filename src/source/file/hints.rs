//! What a caller says about a grid file's bytes: the raw samples' size and type, and the
//! encoding of a colour tile.

/// What a raw file cannot say about itself. Ignored for formats whose header states the size.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GridHints {
    /// Samples along x (columns).
    pub nx: Option<usize>,
    /// Samples along y (rows).
    pub ny: Option<usize>,
    /// The sample type of raw data.
    pub dtype: Option<RawType>,
    /// How a colour PNG tile encodes heights.
    pub encoding: Option<Encoding>,
}

/// How a web-map elevation tile (an 8-bit RGB or RGBA PNG) encodes each pixel's height.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Encoding {
    /// Mapbox Terrain-RGB: height = −10000 + (R·65536 + G·256 + B) · 0.1 metres.
    TerrainRgb,
    /// Terrarium (Mapzen, AWS Terrain Tiles): height = R·256 + G + B/256 − 32768 metres.
    Terrarium,
}

impl Encoding {
    /// `"terrain-rgb"` or `"terrarium"`, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::TerrainRgb => "terrain-rgb",
            Encoding::Terrarium => "terrarium",
        }
    }

    /// The encoding `name` spells, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        [Encoding::TerrainRgb, Encoding::Terrarium].into_iter().find(|e| e.name() == name)
    }

    /// The height of a pixel of colour (r, g, b). Exact in f64 but for Terrain-RGB's tenths,
    /// which are the nearest f64 to the decimal height (an integer count of tenths, divided).
    #[inline]
    pub fn height(self, [r, g, b]: [u8; 3]) -> f64 {
        let (r, g, b) = (u32::from(r), u32::from(g), u32::from(b));
        match self {
            Encoding::TerrainRgb => f64::from((r << 16 | g << 8 | b) as i32 - 100_000) / 10.0,
            Encoding::Terrarium => f64::from(r * 256 + g) - 32768.0 + f64::from(b) / 256.0,
        }
    }
}

/// The sample type of raw data: little-endian IEEE floats, rows from the top down.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RawType {
    /// 4-byte little-endian IEEE 754 floats.
    F32,
    /// 8-byte little-endian IEEE 754 floats.
    F64,
}

impl RawType {
    /// `"f32"` or `"f64"`, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            RawType::F32 => "f32",
            RawType::F64 => "f64",
        }
    }

    /// The type `name` spells (`"f32"` or `"f64"`), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "f32" => Some(RawType::F32),
            "f64" => Some(RawType::F64),
            _ => None,
        }
    }

    /// Bytes per sample: 4 or 8.
    pub fn size(self) -> usize {
        match self {
            RawType::F32 => 4,
            RawType::F64 => 8,
        }
    }
}

/// nx·ny·(4|8) when all three raw hints are given.
pub(super) fn raw_size(hints: &GridHints) -> Option<u64> {
    let (nx, ny, dtype) = (hints.nx?, hints.ny?, hints.dtype?);
    (nx as u64).checked_mul(ny as u64)?.checked_mul(dtype.size() as u64)
}
