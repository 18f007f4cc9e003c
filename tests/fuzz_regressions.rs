//! Replays the fuzz seeds and every input that once crashed the fuzz
//! target (`fuzz/regressions/`) through the same decode + restore path:
//! each must give a result or a typed error that is not internal.

use std::path::Path;

#[test]
fn fuzz_seeds_and_regressions_give_results_or_clear_errors() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut n = 0;
    for dir in ["seeds", "regressions"] {
        let Ok(rd) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        for entry in rd {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "md") {
                continue;
            }
            let data = std::fs::read(&path).unwrap();
            if let Err(e) = uwhl::files::pipeline::fuzz_one(&data) {
                assert!(e.kind != uwhl::Kind::Internal, "{}: {e}", path.display());
            }
            n += 1;
        }
    }
    assert!(n >= 10, "only {n} inputs replayed");
}

#[test]
fn metadata_seeds_give_results_not_panics() {
    use uwhl::files::exif::fuzzing;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz").join("meta_seeds");
    type Target = (&'static str, fn(&[u8]));
    let targets: [Target; 5] = [
        ("exif", fuzzing::exif),
        ("xmp", fuzzing::xmp),
        ("icc", fuzzing::icc),
        ("container", fuzzing::container),
        ("carry", fuzzing::carry),
    ];
    let mut n = 0;
    for (dir, body) in targets {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            let data = std::fs::read(entry.unwrap().path()).unwrap();
            body(&data);
            n += 1;
        }
    }
    assert!(n >= 20, "only {n} metadata seeds replayed");
}
