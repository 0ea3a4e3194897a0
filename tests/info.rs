//! `voxlab info FILE`: the grid and every palette entry of a .vox or an experiment, a
//! mesh's triangles and materials; other files are refused with the path named.

mod common;

use std::path::Path;

#[test]
fn info_lists_the_palette_with_counts_that_add_up() {
    let deer = common::shared_data("deer.vox");
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
    let text = voxlab::info::describe(&common::shared_data("bunny.obj")).unwrap();
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
