//! `voxlab info FILE`: the grid and every palette entry of a .vox or an experiment, a
//! mesh's triangles and materials; other files are refused with the path named.

mod common;

use std::path::Path;

#[test]
fn info_lists_the_palette_with_counts_that_add_up() {
    let deer = common::example_data("deer.vox");
    let text = voxlab::info::describe(&deer).unwrap();
    let v = voxlab::scene::load_vox(&deer, None).unwrap();
    let occupied = v.grid.data().iter().filter(|&&m| m != 0).count();
    assert!(text.contains(&format!("{occupied} occupied")), "{text}");
    // One line per palette entry but void, each with its voxel count; they add up.
    let counts: Vec<u64> = text
        .lines()
        .filter(|l| l.contains(" voxels  #"))
        .map(|l| {
            let before = l.split(" voxels").next().unwrap();
            before.split_whitespace().last().unwrap().parse().unwrap()
        })
        .collect();
    assert_eq!(counts.len(), v.materials.len() - 1);
    assert_eq!(counts.iter().sum::<u64>(), occupied as u64);
    assert!(text.contains("MagicaVoxel index"));

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = voxlab::info::describe(&root.join("experiments/baseline.toml")).unwrap();
    assert!(
        text.contains("16x16x16") && text.contains("glass") && text.contains("3 light(s)"),
        "{text}"
    );
    let text = voxlab::info::describe(&common::example_data("bunny.obj")).unwrap();
    assert!(
        text.contains("mesh: ") && text.contains("triangles"),
        "{text}"
    );
    let err = voxlab::info::describe(&root.join("README.md"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("README.md") && err.contains(".vox"), "{err}");
    let err = format!(
        "{:#}",
        voxlab::info::describe(&root.join("no-such.vox")).unwrap_err()
    );
    assert!(err.contains("no-such.vox"), "{err}");
}

/// A grid held only as its tree: counts from the tree that add up to the dense grid's,
/// and the tree's size said.
#[test]
fn info_on_a_grid_held_sparse_counts_from_the_tree() {
    let dir = std::env::temp_dir().join(format!("voxlab-info-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("big.toml");
    std::fs::write(
        &path,
        "[scene]\nsize = 1024\n\n[[scene.boxes]]\nmin = [400, 400, 400]\n\
         max = [500, 500, 500]\nmaterial = \"glass\"\n",
    )
    .unwrap();
    let text = voxlab::info::describe(&path).unwrap();
    assert!(text.contains("held as its sparse tree only"), "{text}");
    // The seed's semi-solid cube (128^3, voxels 448..576) less its overlap with the box
    // (448..500 on every axis).
    assert!(
        text.contains(&format!("{} voxels", 128u64.pow(3) - 52u64.pow(3))),
        "{text}"
    );
    assert!(text.contains("1073741824 voxels"), "{text}");
    std::fs::remove_dir_all(&dir).unwrap();
}
