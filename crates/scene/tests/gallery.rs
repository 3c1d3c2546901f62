//! The gallery's scenes (`docs/gallery/*.toml`, the pictures in docs/phenomena.md) are
//! scenes users copy: each loads and validates; the campfire under a pot keeps running
//! in a gusty wind.

use std::path::PathBuf;

use phenomena_scene::{Assets, Runner};

fn gallery() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/gallery")
}

#[test]
fn every_gallery_scene_loads() {
    let mut seen = 0;
    for entry in std::fs::read_dir(gallery()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            phenomena_scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            seen += 1;
        }
    }
    assert!(seen >= 2, "{seen} gallery scenes");
}

#[test]
fn the_pot_over_the_campfire_holds_in_a_gust() {
    // The pot scene with flame-puffing.toml's gust (0.35 N/m³ at 1.5 s, -0.1 at 2.5 s).
    // The wind displaces the air's rows and the pot with them; when the particles met
    // a pot that stayed put, the air dragged them into it and they piled up under it
    // until the SPH refused the crowd, at frame 125 (2026-12-06).
    let text = std::fs::read_to_string(gallery().join("flame-pot.toml")).unwrap();
    let gust = "\n[[flame.wind.keys]]\ntime_s = 0.0\nforce_n_m3 = [0.0, 0.0, 0.0]\n\
        [[flame.wind.keys]]\ntime_s = 1.5\nforce_n_m3 = [0.35, 0.0, 0.0]\n\
        [[flame.wind.keys]]\ntime_s = 2.5\nforce_n_m3 = [-0.1, 0.0, 0.0]\n";
    let scene = phenomena_scene::parse(&format!("{text}{gust}"), "flame-pot.toml + gust").expect("valid");
    let mut runner = Runner::new(&scene, &Assets::none()).expect("builds");
    for frame in 0..160 {
        if let Err(e) = runner.step() {
            panic!("frame {frame}: {e}");
        }
    }
}
