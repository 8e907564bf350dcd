//! Rendering and labelling tests with hand-computed expectations.

use deepfoids_env::cage::Cage;
use deepfoids_env::config::CageConfig;
use deepfoids_env::sun::SunPlace;
use deepfoids_render::dataset::{rle_counts, rle_from_string, rle_string, yolo_labels};
use deepfoids_render::mesh::{FishMesh, FishStyle};
use deepfoids_render::render::fish_axes;
use deepfoids_render::{
    Camera, Conditions, FishPose, Frame, Light, RenderConfig, Renderer, Water, WaterParams,
};
use glam::Vec3;

const PLACE: SunPlace = SunPlace {
    latitude_deg: 38.465,
    longitude_deg: 141.480,
    utc_offset_hours: 9.0,
};

fn coho_mesh() -> FishMesh {
    FishMesh::standard(&FishStyle::for_species(
        "coho",
        [0.12, 0.25, 1.0],
        [0.42, 0.48, 0.55],
    ))
}

fn renderer() -> Renderer {
    let cage = Cage::new(CageConfig::Cube { edge: 6.0 });
    Renderer::new(
        RenderConfig {
            tail_beat: false,
            ..RenderConfig::default()
        },
        vec![coho_mesh()],
        Renderer::faces_of(&cage),
    )
}

fn conditions(hours: f64) -> Conditions {
    Conditions {
        light: Light::new(PLACE, 2021, 3, 15, hours),
        noon: Light::new(PLACE, 2021, 3, 15, PLACE.solar_noon_hours(2021, 3, 15)),
        water: Water::new(WaterParams::default(), true),
    }
}

/// A pinhole 2 m down at z = 2.8, looking along −z (up is +y).
fn side_camera(fov_deg: f32, width: u32, height: u32) -> Camera {
    Camera::pinhole(
        Vec3::new(0.0, -2.0, 2.8),
        -Vec3::Z,
        Vec3::Y,
        fov_deg,
        width,
        height,
    )
}

fn fish_at(position: Vec3, heading: Vec3, bl: f32) -> FishPose {
    FishPose {
        position,
        heading,
        roll: 0.0,
        bl,
        speed: 0.0,
        species: 0,
        tail_phase: 0.0,
    }
}

/// Min/max of the projections of every mesh vertex of `f`.
fn analytic_box(mesh: &FishMesh, f: &FishPose, cam: &Camera) -> [f32; 4] {
    let axes = fish_axes(f.heading, f.roll);
    let mut b = [f32::MAX, f32::MAX, f32::MIN, f32::MIN];
    for p in &mesh.positions {
        let q = cam.project(f.position + axes * (*p * f.bl)).unwrap();
        b[0] = b[0].min(q.x);
        b[1] = b[1].min(q.y);
        b[2] = b[2].max(q.x);
        b[3] = b[3].max(q.y);
    }
    b
}

fn assert_box_close(label: [u32; 4], analytic: [f32; 4]) {
    for k in 0..4 {
        assert!(
            (label[k] as f32 - analytic[k]).abs() <= 1.0,
            "box {label:?} vs analytic {analytic:?}"
        );
    }
}

/// A fish 2 m in front of a side camera, seen obliquely: the full and the
/// visible box equal the projected mesh's bounds to within a pixel.
#[test]
fn single_fish_box_matches_the_projected_mesh_pinhole() {
    let r = renderer();
    let cam = side_camera(90.0, 640, 360);
    let f = fish_at(
        Vec3::new(0.3, -1.9, 0.8),
        Vec3::new(1.0, 0.1, 0.4).normalize(),
        0.5,
    );
    let frame = r.render(&[f], &cam, &conditions(11.5));
    assert_eq!(frame.fish.len(), 1);
    let l = &frame.fish[0];
    let analytic = analytic_box(&r.meshes[0], &f, &cam);
    assert_box_close(l.box_full, analytic);
    assert_eq!(l.box_visible, Some(l.box_full));
    assert_eq!(l.visibility, 1.0);
    assert!(!l.truncated);
    // The mask holds exactly the visible pixels, with id fish + 1.
    let n = frame.ids.iter().filter(|&&v| v == 1).count() as u32;
    assert_eq!(n, l.visible_pixels);
    // 3D box: corners at ±half extents around the centre; the camera
    // coordinates are the world corners seen from the camera (both rounded to mm).
    let c = l
        .box3d_world
        .iter()
        .fold(Vec3::ZERO, |s, p| s + Vec3::from(*p))
        / 8.0;
    assert!((c - f.position).length() < 0.05 * f.bl, "{c}");
    for (w, k) in l.box3d_world.iter().zip(&l.box3d_camera) {
        assert!((cam.to_camera(Vec3::from(*w)) - Vec3::from(*k)).length() < 2e-3);
    }
}

/// The same with the bottom fisheye: a fish 1.5 m above and 1 m to the side.
#[test]
fn single_fish_box_matches_the_projected_mesh_fisheye() {
    let r = renderer();
    let cam = Camera::fisheye(
        Vec3::new(0.0, -5.8, 0.0),
        Vec3::Y,
        -Vec3::Z,
        235.0,
        800,
        800,
    );
    let f = fish_at(
        Vec3::new(1.0, -4.3, 0.2),
        Vec3::new(0.2, 0.0, 1.0).normalize(),
        0.5,
    );
    let frame = r.render(&[f], &cam, &conditions(11.5));
    let l = &frame.fish[0];
    assert_box_close(l.box_full, analytic_box(&r.meshes[0], &f, &cam));
    assert!(!l.truncated && l.visibility == 1.0);
}

/// Two fish on one line of sight: the near one hides part of the far one.
/// The far one's visibility is below 1, the near one's is 1, and every mask
/// pixel with id k lies inside box k.
#[test]
fn two_fish_in_line_occlude() {
    let r = renderer();
    let cam = side_camera(90.0, 480, 320);
    let near = fish_at(Vec3::new(0.0, -2.0, 1.8), Vec3::X, 0.5);
    let far = fish_at(Vec3::new(0.1, -2.07, 0.3), Vec3::X, 0.5);
    let frame = r.render(&[near, far], &cam, &conditions(11.5));
    let get = |k: usize| frame.fish.iter().find(|l| l.fish == k).unwrap();
    let (ln, lf) = (get(0), get(1));
    assert_eq!(ln.visibility, 1.0);
    assert!(
        lf.visibility < 1.0 && lf.visibility > 0.0,
        "{}",
        lf.visibility
    );
    assert!(lf.full_pixels > lf.visible_pixels);
    for (k, l) in [(1u16, ln), (2u16, lf)] {
        let [x0, y0, x1, y1] = l.box_visible.unwrap();
        let mut n = 0;
        for y in 0..frame.height {
            for x in 0..frame.width {
                if frame.ids[(y * frame.width + x) as usize] == k {
                    assert!(x >= x0 && x < x1 && y >= y0 && y < y1);
                    n += 1;
                }
            }
        }
        assert_eq!(n, l.visible_pixels);
    }
    // Swapping the order in the list changes nothing: the depth test decides.
    let swapped = r.render(&[far, near], &cam, &conditions(11.5));
    assert_eq!(
        swapped.ids.iter().filter(|&&v| v == 1).count() as u32,
        lf.visible_pixels
    );
}

/// A fish half outside the image is flagged truncated; its full box is clipped.
#[test]
fn fish_at_the_border_is_truncated() {
    let r = renderer();
    let cam = side_camera(90.0, 320, 240);
    // At 1.5 m the image's right edge is at x = 1.5 m.
    let f = fish_at(Vec3::new(1.5, -2.0, 1.3), Vec3::X, 0.5);
    let frame = r.render(&[f], &cam, &conditions(11.5));
    let l = &frame.fish[0];
    assert!(l.truncated);
    assert_eq!(l.box_full[2], 320);
    let inside = fish_at(Vec3::new(0.0, -2.0, 1.3), Vec3::X, 0.5);
    assert!(!r.render(&[inside], &cam, &conditions(11.5)).fish[0].truncated);
}

/// A fish that crosses the near plane is clipped, not dropped.
#[test]
fn fish_through_the_near_plane_is_clipped() {
    let r = renderer();
    let cam = side_camera(90.0, 320, 240);
    let f = fish_at(Vec3::new(0.0, -2.1, 2.7), Vec3::Z, 0.5);
    let frame = r.render(&[f], &cam, &conditions(11.5));
    assert!(frame.fish[0].truncated);
    assert!(
        frame.fish[0].visible_pixels > 1000,
        "{}",
        frame.fish[0].visible_pixels
    );
}

/// Back-face culling of the closed body loses no pixel of the silhouette:
/// seen from any side, the fish covers what its vertices' hull suggests and
/// the silhouette has no holes along its middle row.
#[test]
fn silhouette_has_no_holes() {
    let r = renderer();
    let cam = side_camera(60.0, 400, 300);
    for heading in [
        Vec3::X,
        Vec3::Z,
        -Vec3::Z,
        Vec3::new(1.0, 0.5, 1.0).normalize(),
    ] {
        let f = fish_at(Vec3::new(0.0, -2.0, 1.8), heading, 0.5);
        let frame = r.render(&[f], &cam, &conditions(11.5));
        let l = &frame.fish[0];
        let [x0, y0, x1, y1] = l.box_full;
        let ymid = (y0 + y1) / 2;
        let row: Vec<bool> = (x0..x1)
            .map(|x| frame.ids[(ymid * frame.width + x) as usize] == 1)
            .collect();
        let first = row.iter().position(|&b| b).unwrap();
        let last = row.iter().rposition(|&b| b).unwrap();
        assert!(
            row[first..=last].iter().all(|&b| b),
            "hole for heading {heading}"
        );
    }
}

/// Night is dark: at 23:00 every pixel is black.
#[test]
fn night_is_black() {
    let r = renderer();
    let cam = side_camera(90.0, 160, 90);
    let f = fish_at(Vec3::new(0.0, -2.0, 1.0), Vec3::X, 0.5);
    let frame = r.render(&[f], &cam, &conditions(23.0));
    assert!(frame.rgb.iter().all(|&v| v == 0));
    // The fish is in view but cannot be seen: not labelled for detectors.
    assert_eq!(frame.in_view_count(), 1);
    assert_eq!(frame.visible_count(), 0);
    assert_eq!(frame.fish[0].contrast, 0.0);
    assert_eq!(yolo_labels(&frame), "");
    let day = r.render(&[f], &cam, &conditions(11.5));
    let mean = day.rgb.iter().map(|&v| v as f64).sum::<f64>() / day.rgb.len() as f64;
    assert!(mean > 30.0, "{mean}");
}

/// Turbid water hides a far fish's contrast: the difference between fish
/// pixels and open water shrinks as sediment rises.
#[test]
fn turbid_water_lowers_contrast() {
    let r = renderer();
    let cam = side_camera(90.0, 320, 180);
    let f = fish_at(Vec3::new(0.0, -2.0, 0.0), Vec3::X, 0.5);
    let contrast = |sediment: f32| {
        let mut c = conditions(11.5);
        c.water = Water::new(
            WaterParams {
                sediment,
                ..WaterParams::default()
            },
            true,
        );
        let fr = r.render(&[f], &cam, &c);
        let mean = |want_fish: bool| {
            let (mut s, mut n) = (0.0, 0.0);
            for (k, &id) in fr.ids.iter().enumerate() {
                if (id != 0) == want_fish {
                    s += fr.rgb[3 * k + 1] as f64;
                    n += 1.0;
                }
            }
            s / n
        };
        (mean(true) - mean(false)).abs()
    };
    let (clear, turbid) = (contrast(0.0), contrast(5.0));
    assert!(turbid < 0.5 * clear, "clear {clear}, turbid {turbid}");
}

fn frame_with(ids: Vec<u16>, w: u32, h: u32) -> Frame {
    Frame {
        width: w,
        height: h,
        rgb: vec![0; (w * h * 3) as usize],
        ids,
        fish: vec![],
        gain: 1.0,
    }
}

/// COCO RLE by hand: a 4 × 3 image (w = 4, h = 3) with id 7 at (x, y) = (1, 0),
/// (1, 1), (2, 1). Column-major indices x·3 + y: 3, 4, 7 → counts
/// [3, 2, 2, 1, 4]; the compressed string decodes back.
#[test]
fn rle_counts_by_hand() {
    let mut ids = vec![0u16; 12];
    for (x, y) in [(1, 0), (1, 1), (2, 1)] {
        ids[y * 4 + x] = 7;
    }
    let f = frame_with(ids, 4, 3);
    let c = rle_counts(&f, 7, [1, 0, 3, 2]);
    assert_eq!(c, vec![3, 2, 2, 1, 4]);
    assert_eq!(rle_from_string(&rle_string(&c)), c);
    let big = vec![0, 100_000, 3, 70_000, 1, 2];
    assert_eq!(rle_from_string(&rle_string(&big)), big);
}

/// YOLO lines: class and a box normalised to [0, 1] for a fish at the border.
#[test]
fn yolo_labels_are_normalised() {
    let r = renderer();
    let cam = side_camera(90.0, 320, 240);
    let fish = [
        fish_at(Vec3::new(1.5, -2.0, 1.3), Vec3::X, 0.5),
        fish_at(Vec3::new(-0.3, -1.6, 1.0), Vec3::Z, 0.4),
    ];
    let frame = r.render(&fish, &cam, &conditions(11.5));
    let text = yolo_labels(&frame);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2);
    for line in lines {
        let v: Vec<f64> = line.split(' ').map(|s| s.parse().unwrap()).collect();
        assert_eq!(v[0], 0.0);
        for x in &v[1..] {
            assert!((0.0..=1.0).contains(x), "{line}");
        }
        assert!(v[1] - v[3] / 2.0 >= -1e-6 && v[1] + v[3] / 2.0 <= 1.0 + 1e-6);
    }
}

/// A fish's contrast is the mean, over its visible pixels, of the largest
/// channel difference between the frame and the same frame without the fish
/// (the exposure does not depend on the fish).
#[test]
fn contrast_is_measured_against_the_frame_without_the_fish() {
    let r = renderer();
    let cam = side_camera(90.0, 320, 180);
    let f = fish_at(
        Vec3::new(0.2, -2.1, 1.5),
        Vec3::new(1.0, 0.0, 0.3).normalize(),
        0.5,
    );
    let cond = conditions(10.0);
    let with = r.render(&[f], &cam, &cond);
    let without = r.render(&[], &cam, &cond);
    assert!(without.fish.is_empty());
    let (mut sum, mut n) = (0u64, 0u64);
    for (k, &id) in with.ids.iter().enumerate() {
        if id == 1 {
            sum += (0..3)
                .map(|j| with.rgb[3 * k + j].abs_diff(without.rgb[3 * k + j]))
                .max()
                .unwrap() as u64;
            n += 1;
        }
    }
    let want = sum as f32 / (255.0 * n as f32);
    let l = &with.fish[0];
    assert!((l.contrast - want).abs() < 1e-4, "{} vs {want}", l.contrast);
    assert!(l.contrast > 0.1 && l.detectable, "{}", l.contrast);
    // Pixels away from the fish are the same in both frames.
    let same = with
        .ids
        .iter()
        .enumerate()
        .filter(|&(_, &id)| id == 0)
        .all(|(k, _)| with.rgb[3 * k..3 * k + 3] == without.rgb[3 * k..3 * k + 3]);
    assert!(same);
}

/// In turbid water a fish 0.35 m from the camera is labelled and the same
/// fish 2 m away, in view and unoccluded, is too faint to be: at 550 nm the
/// extinction is ≈ 5.5 /m, so its contrast falls by e^(−11).
#[test]
fn faint_fish_in_turbid_water_are_not_labelled() {
    let r = renderer();
    let cam = side_camera(90.0, 320, 180);
    let mut cond = conditions(11.5);
    cond.water = Water::new(
        WaterParams {
            chlorophyll: 5.0,
            sediment: 5.0,
            small_particles: 2.0,
            large_particles: 2.0,
        },
        true,
    );
    assert!(cond.water.c.y > 5.0, "{}", cond.water.c);
    let near = fish_at(Vec3::new(-0.3, -2.0, 2.45), Vec3::X, 0.5);
    let far = fish_at(Vec3::new(0.6, -2.0, 0.8), Vec3::X, 0.5);
    let frame = r.render(&[near, far], &cam, &cond);
    let get = |k: usize| frame.fish.iter().find(|l| l.fish == k).unwrap();
    assert!(get(0).detectable, "{}", get(0).contrast);
    assert_eq!(get(1).visibility, 1.0);
    assert!(
        !get(1).detectable && get(1).contrast < 0.01,
        "{}",
        get(1).contrast
    );
    assert_eq!((frame.in_view_count(), frame.visible_count()), (2, 1));
    assert_eq!(yolo_labels(&frame).lines().count(), 1);
}

/// `--randomize` draws times when the sun is up: over 200 clips of the coho
/// scene every drawn time lies in 5:30–19:00 with the sun at least 2° high,
/// December clips start after sunrise (≈ 6:45 at Onagawa) and summer clips
/// (May–July, sunrise ≈ 4:15) reach before 7:00. The same seed draws the
/// same clips. The water is skewed to clear and bounded by the sites'
/// attenuation (Table 4.3): every extinction at 550 nm lies in 0.13–3.0 /m,
/// the median near 1.4 /m, and murky clips above 2.5 /m still come up.
#[test]
fn randomized_clips_are_drawn_in_daylight() {
    use deepfoids_render::{CameraKind, ClipParams, RandomRanges};
    let dirs = deepfoids_env::ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"));
    let scene =
        deepfoids_env::Scene::load(&dirs, "coho_default", deepfoids_env::Phase::Pretrain).unwrap();
    let ranges = RandomRanges::default();
    let place = deepfoids_render::setup::site_place(&scene);
    let (mut early_summer, mut december, mut ext) = (false, vec![], vec![]);
    for clip in 0..200 {
        let c = ClipParams::random(&scene, clip, 7, CameraKind::Side, &ranges).unwrap();
        assert_eq!(
            c,
            ClipParams::random(&scene, clip, 7, CameraKind::Side, &ranges).unwrap()
        );
        assert!((5.5..=19.0).contains(&c.hours), "{}", c.hours);
        let el = place
            .position(c.year, c.month, c.day, c.hours)
            .elevation_deg;
        assert!(el >= 2.0, "clip {clip}: {c:?} has the sun at {el}°");
        if c.month == 12 {
            december.push(c.hours);
        }
        ext.push(Water::new(c.water, true).c.y);
        early_summer |= (5..=7).contains(&c.month) && c.hours < 7.0;
    }
    assert!(december.iter().all(|&h| h > 6.7), "{december:?}");
    assert!(!december.is_empty() && early_summer);
    ext.sort_by(f32::total_cmp);
    let median = ext[ext.len() / 2];
    assert!((0.9..1.8).contains(&median), "median extinction {median}");
    assert!(ext[0] >= 0.13 && ext[ext.len() - 1] <= 3.0, "{ext:?}");
    assert!(ext[ext.len() - 1] > 2.5, "{ext:?}");
    // A redrawn water is another draw, the same for the same attempt, in range.
    let c = ClipParams::random(&scene, 3, 7, CameraKind::Side, &ranges).unwrap();
    let r1 = c.redraw_water(7, 1, &ranges).unwrap();
    assert_ne!(r1.water, c.water);
    assert_eq!(r1, c.redraw_water(7, 1, &ranges).unwrap());
    assert_eq!((r1.water_attempt, r1.hours), (1, c.hours));
    assert!((0.13..=3.0).contains(&Water::new(r1.water, true).c.y));
}

/// Clips are split evenly: every 5th clip for a fifth; one clip is all
/// training; two clips with a small share still hold one out.
#[test]
fn validation_clips_are_whole_clips_spread_evenly() {
    use deepfoids_render::Split;
    let val: Vec<usize> = (0..10)
        .filter(|&c| Split::of_clip(c, 10, 0.2) == Split::Val)
        .collect();
    assert_eq!(val, vec![4, 9]);
    assert_eq!(Split::of_clip(0, 1, 0.2), Split::Train);
    assert_eq!(Split::of_clip(1, 2, 0.2), Split::Val);
    assert_eq!(Split::of_clip(0, 2, 0.2), Split::Train);
    assert!((0..7).all(|c| Split::of_clip(c, 7, 0.0) == Split::Train));
}

/// The background is made once per camera and conditions: a second frame
/// under the same ones reuses it, other conditions make a new one, and every
/// frame is what a fresh renderer draws (pixels and labels), with the fish
/// where it is now.
#[test]
fn the_background_is_kept_per_camera_and_conditions() {
    let r = renderer();
    let cam = side_camera(90.0, 160, 90);
    let f = |x: f32| fish_at(Vec3::new(x, -2.0, 1.0), Vec3::X, 0.5);
    let (noon, evening) = (conditions(11.5), conditions(17.0));
    let kept = r.background(&cam, &noon);
    let first = r.render(&[f(0.0)], &cam, &noon);
    let moved = r.render(&[f(0.3)], &cam, &noon);
    assert!(std::sync::Arc::ptr_eq(&kept, &r.background(&cam, &noon)));
    let later = r.render(&[f(0.0)], &cam, &evening);
    assert!(!std::sync::Arc::ptr_eq(
        &kept,
        &r.background(&cam, &evening)
    ));
    assert_ne!(first.rgb, moved.rgb, "the fish moved");
    for (frame, x, cond) in [
        (&first, 0.0, noon),
        (&moved, 0.3, noon),
        (&later, 0.0, evening),
    ] {
        let fresh = renderer().render(&[f(x)], &cam, &cond);
        assert_eq!(frame.rgb, fresh.rgb);
        assert_eq!(frame.fish, fresh.fish);
    }
    // Where no fish is, the frame is its background; the fish is not.
    let bg = &r.background(&cam, &evening).rgb;
    let fish_px = |k: usize| later.ids[k] != 0;
    assert!(
        (0..later.ids.len())
            .all(|k| fish_px(k) || later.rgb[3 * k..3 * k + 3] == bg[3 * k..3 * k + 3])
    );
    assert!(
        (0..later.ids.len())
            .any(|k| fish_px(k) && later.rgb[3 * k..3 * k + 3] != bg[3 * k..3 * k + 3])
    );
}

/// A clip's light is held for `LIGHT_STEP_SECONDS` (10 s) of the clock:
/// 1 s and 6 s past 10:00 share it, 11 s past is the next step's; the
/// water does not change.
#[test]
fn the_light_is_held_for_a_step() {
    use deepfoids_render::setup::LIGHT_STEP_SECONDS;
    use deepfoids_render::{CameraKind, ClipParams, RandomRanges};
    assert_eq!(LIGHT_STEP_SECONDS, 10.0);
    let dirs = deepfoids_env::ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"));
    let scene =
        deepfoids_env::Scene::load(&dirs, "coho_default", deepfoids_env::Phase::Pretrain).unwrap();
    let c = ClipParams::random(&scene, 0, 7, CameraKind::Side, &RandomRanges::default()).unwrap();
    let at = |s: f64| c.conditions(&scene, 10.0 + s / 3600.0, true);
    assert_eq!(at(1.0), at(6.0));
    assert_ne!(at(1.0).light, at(11.0).light);
    assert_eq!(at(1.0).water, at(11.0).water);
    assert_eq!(
        at(1.0).light,
        Light::new(
            deepfoids_render::setup::site_place(&scene),
            c.year,
            c.month,
            c.day,
            10.0
        )
    );
}

/// Frames written one behind their rendering (`FrameWriter`) are byte for
/// byte the frames `write_frame` writes at once; the last one appears only
/// at `finish`. The frame JSON prints each f32 as itself (2.636, not the
/// f64 widening 2.63599991798401).
#[test]
fn the_frame_writer_writes_what_write_frame_writes() {
    use deepfoids_render::{Dataset, FrameMeta, FrameWriter, ImageFormat, Split};
    let r = renderer();
    let cam = side_camera(60.0, 160, 120);
    let fish = [fish_at(Vec3::new(0.1, -2.0, 0.6), Vec3::X, 0.5)];
    let meta = |i: usize| FrameMeta {
        clip: 0,
        time: i as f64 * 0.2,
        clock_hours: 11.0,
        sun_elevation_deg: 40.0,
        camera: cam,
        split: Split::Train,
        water_attempt: 0,
    };
    let render = |i: usize| r.render(&fish, &cam, &conditions(11.0 + i as f64));
    let root = std::env::temp_dir().join(format!("deepfoids-writer-{}", std::process::id()));
    let dataset = |name: &str| {
        let names = |s: &str| vec![s.to_string()];
        Dataset::new(
            &root.join(name),
            ImageFormat::Jpg,
            names("coho"),
            names("regular"),
        )
    };
    let (behind, direct) = (dataset("behind"), dataset("direct"));
    let mut writer = FrameWriter::new(&behind, &[0]);
    for i in 0..3 {
        let visible = writer.next(i, meta(i), || render(i)).unwrap();
        let frame = render(i);
        assert_eq!(visible, frame.visible_count());
        direct.write_frame(i, &frame, &[0], &meta(i)).unwrap();
    }
    assert!(behind.frame_done(1) && !behind.frame_done(2));
    writer.finish().unwrap();
    for i in 0..3 {
        for path in [
            Dataset::image_path,
            Dataset::mask_path,
            Dataset::label_path,
            Dataset::frame_json_path,
        ] {
            let read = |d: &Dataset| std::fs::read(path(d, i)).unwrap();
            assert_eq!(
                read(&behind),
                read(&direct),
                "{}",
                path(&behind, i).display()
            );
        }
    }
    let text = std::fs::read_to_string(direct.frame_json_path(0)).unwrap();
    let distance = render(0).fish[0].distance;
    assert!(
        text.contains(&format!("\"distance\":{distance},")),
        "{distance} as written: {}",
        &text[text.find("\"distance\"").unwrap()..][..30]
    );
    std::fs::remove_dir_all(&root).unwrap();
}
