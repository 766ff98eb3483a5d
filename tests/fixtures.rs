//! The committed fixtures are exactly what the generator makes today.

use ellip::synth::fixtures::write_fixtures;
use std::path::Path;

#[test]
fn regenerating_the_fixtures_reproduces_them_byte_for_byte() {
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/meshes");
    let dir = std::env::temp_dir().join(format!("ellip-fixtures-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let written = write_fixtures(&dir).expect("fixtures generate");
    assert!(written.len() >= 11);
    for path in &written {
        let name = path.file_name().unwrap();
        let fresh = std::fs::read(path).unwrap();
        let old = std::fs::read(committed.join(name))
            .unwrap_or_else(|_| panic!("{name:?} is not committed: run `ellip fixtures`"));
        assert!(
            fresh == old,
            "{name:?} differs from the committed copy; if the change is deliberate, run \
             `cargo run -- fixtures` and commit the result"
        );
        assert!(fresh.len() < 1 << 20, "{name:?} is over 1 MB");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
