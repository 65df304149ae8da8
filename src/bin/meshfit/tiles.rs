//! `meshfit tiles`: a DEM's terrain pyramid for static hosting: `layer.json` and every
//! `z/x/y.terrain` (quantized-mesh-1.0, uncompressed), the tiles shared out over every core,
//! with a progress bar on a terminal.

use anyhow::{Context, Result, anyhow};
use clap::Args;
use meshfit::tiles::{Dem, Pyramid, TileId, Wanted};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

#[derive(Args)]
pub(crate) struct TilesArgs {
    /// The DEM: a GeoTIFF in EPSG:4326 (longitude and latitude on WGS84).
    #[arg(value_name = "DEM")]
    dem: PathBuf,
    /// The directory to write layer.json and the z/x/y.terrain files into (made if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// The first level below the two root tiles, which are always written.
    #[arg(long, default_value_t = 0, value_name = "Z")]
    min_zoom: u8,
    /// The last level; by default where a tile's 65 samples a side reach the DEM's pixel.
    #[arg(long, value_name = "Z")]
    max_zoom: Option<u8>,
    /// Each tile keeps within this fraction of its level's geometric error (Cesium's
    /// 77,067 m / 2^z) of the DEM.
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    error_factor: f64,
}

pub(crate) fn tiles(args: &TilesArgs) -> Result<()> {
    let path = &args.dem;
    // Read by blocks, as the server reads a file: the same tiles, and a DEM larger than
    // memory works.
    let file = std::fs::File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let dem = Dem::open(Box::new(std::io::BufReader::new(file)), usize::MAX)
        .with_context(|| format!("{}", path.display()))?;
    let pyramid = Pyramid::new(&dem, args.min_zoom, args.max_zoom, args.error_factor)?;
    let tiles = pyramid.tiles();
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    // Tiles are independent once their sides are fixed by their own values: any order, any
    // number of threads, the same bytes. The first failure stops every thread.
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let failure = Mutex::new(None);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    // Drawn on a terminal only (indicatif hides it on a pipe or a file, as in CI).
    let progress = indicatif::ProgressBar::new(tiles.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} tiles, {per_sec}, {eta} left")
            .expect("a valid template"),
    );
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                while !stop.load(Ordering::Relaxed)
                    && let Some(&tile) = tiles.get(next.fetch_add(1, Ordering::Relaxed))
                {
                    if let Err(e) = write_tile(&pyramid, tile, &args.out) {
                        stop.store(true, Ordering::Relaxed);
                        failure.lock().unwrap_or_else(std::sync::PoisonError::into_inner).get_or_insert(e);
                    }
                    progress.inc(1);
                }
            });
        }
    });
    progress.finish_and_clear();
    if let Some(e) = failure.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner) {
        return Err(e);
    }
    // layer.json last, so that it never lists a tile that is not there.
    let name = path.file_stem().map_or_else(|| "terrain".into(), |s| s.to_string_lossy().into_owned());
    let layer = serde_json::to_vec_pretty(&pyramid.layer_json(&name, meshfit::tiles::TILES_VERSION))?;
    write(&args.out.join("layer.json"), &layer)?;
    eprintln!(
        "{} tiles of levels 0..={} in {}; serve the directory and point a terrain provider at it",
        tiles.len(),
        pyramid.max_level(),
        args.out.display()
    );
    Ok(())
}

fn write_tile(pyramid: &Pyramid<'_>, tile: TileId, out: &Path) -> Result<()> {
    let bytes = pyramid
        .tile(tile, Wanted::ALL)?
        .ok_or_else(|| anyhow!("tile {}/{}/{} is not in the pyramid", tile.z, tile.x, tile.y))?;
    let dir = out.join(tile.z.to_string()).join(tile.x.to_string());
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write(&dir.join(format!("{}.terrain", tile.y)), &bytes)
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}
