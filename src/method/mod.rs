//! The method of docs/METHOD.md: [`restore`](crate::restore) step by
//! step, [`Sequence`](crate::Sequence) for frames, one file per section,
//! the parameters and profiles, the Jerlov table. Nothing here touches a
//! file: images come in and results go out as slices.
//!
//! | file | METHOD |
//! |---|---|
//! | `image.rs` | validated image and mask views |
//! | `params.rs` | `Params`, `Input`, `Restoration`, flags, checks, memory estimate |
//! | `profile.rs` | the profiles and their steps (§12) |
//! | `water.rs` | the Jerlov table and custom types (§1) |
//! | `stretch.rs` | contrast stretch and guide image (§3.1, §6) |
//! | `veiling.rs` | edge map, water region, veiling light (§3) |
//! | `sphere.rs` | points on the sphere, nearest-neighbour lookup (§4.3) |
//! | `hazelines.rs` | haze-lines, t~, lower bound (§4, §5) |
//! | `matting.rs` | soft matting and the blend with the lower bound (§4.6, §5) |
//! | `guided.rs` | guided filter, its fast form, the masked fill (§6) |
//! | `recover.rs` | recovery, artifact clamp, display stretch (§7, §8) |
//! | `distance.rs` | the water fitted from a known distance (§13) |
//! | `floor.rs` | distance from the altitude over a flat seabed (§13.7) |
//! | `fallback.rs` | confidence, the unreliable flag, the fallback blend (§12.5) |
//! | `select.rs` | selection sums, scores, exclusion, the choice (§9) |
//! | `pipeline/` | `restore()`, per-type evaluation, fast selection, buffers |
//! | `sequence.rs` | estimates reused from frame to frame (§10) |

stage_modules! {
    distance, fallback, floor, guided, hazelines, image, matting, params, pipeline, profile, recover, select, sequence, sphere, stretch,
    veiling, water,
}
