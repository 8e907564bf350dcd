//! Average precision at IoU 0.5 (one class: mAP50 = AP50), written out so it
//! can be checked by hand.
//!
//! Detections of every image are ranked by falling score. Each in turn is a
//! true positive if it overlaps a not yet matched ground-truth box of its
//! image with IoU ≥ 0.5 (the best such box is taken), else a false positive.
//! Precision and recall after each detection give the curve; AP is the area
//! under its monotone envelope (precision at recall r = the best precision at
//! any recall ≥ r), summed over the recall steps — the all-point
//! interpolation of PASCAL VOC 2010 and later.
//!
//! Fish in view too faint to label (the renderer's contrast below
//! `--min-contrast`) are *ignored*, as COCO ignores crowd regions: a detection
//! that matches no labelled fish but covers an ignored one with IoU ≥ the
//! threshold is neither a true nor a false positive. A detector is then not
//! punished for finding a fish a person could hardly make out.

use crate::boxes::{Detection, iou};

/// AP at `iou_threshold` of `detections[i]` against `truth[i]` per image.
pub fn average_precision(
    detections: &[Vec<Detection>],
    truth: &[Vec<Detection>],
    iou_threshold: f32,
) -> f64 {
    let none = vec![Vec::new(); truth.len()];
    average_precision_ignoring(detections, truth, &none, iou_threshold)
}

/// [`average_precision`] with `ignore[i]`, image `i`'s fish that are neither
/// to be found nor false when found.
pub fn average_precision_ignoring(
    detections: &[Vec<Detection>],
    truth: &[Vec<Detection>],
    ignore: &[Vec<Detection>],
    iou_threshold: f32,
) -> f64 {
    let n_truth: usize = truth.iter().map(Vec::len).sum();
    if n_truth == 0 {
        return 0.0;
    }
    let mut ranked: Vec<(usize, &Detection)> = detections
        .iter()
        .enumerate()
        .flat_map(|(i, d)| d.iter().map(move |x| (i, x)))
        .collect();
    ranked.sort_by(|a, b| b.1.score.total_cmp(&a.1.score));
    let mut matched: Vec<Vec<bool>> = truth.iter().map(|t| vec![false; t.len()]).collect();
    let (mut tp, mut fp) = (0usize, 0usize);
    let mut curve = Vec::with_capacity(ranked.len()); // (recall, precision)
    for (img, d) in ranked {
        let best = truth[img]
            .iter()
            .enumerate()
            .filter(|(k, _)| !matched[img][*k])
            .map(|(k, t)| (k, iou(d, t)))
            .filter(|&(_, v)| v >= iou_threshold)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((k, _)) => {
                matched[img][k] = true;
                tp += 1;
            }
            None if ignore[img].iter().any(|g| iou(d, g) >= iou_threshold) => continue,
            None => fp += 1,
        }
        curve.push((tp as f64 / n_truth as f64, tp as f64 / (tp + fp) as f64));
    }
    // Monotone envelope from the right, then the area over recall steps.
    let mut ap = 0.0;
    let mut prev_recall = 0.0;
    for i in 0..curve.len() {
        let (r, _) = curve[i];
        if r > prev_recall {
            let p = curve[i..].iter().map(|c| c.1).fold(0.0, f64::max);
            ap += (r - prev_recall) * p;
            prev_recall = r;
        }
    }
    ap
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x: f32, score: f32) -> Detection {
        Detection {
            x0: x,
            y0: 0.0,
            x1: x + 10.0,
            y1: 10.0,
            score,
        }
    }

    /// Two images, three true boxes (at x 0 and 50 in image 0, x 0 in image 1).
    /// Ranked detections: 0.9 hits (0, 0) → P 1, R 1/3; 0.8 misses → P 1/2;
    /// 0.7 hits (1, 0) → P 2/3, R 2/3; 0.6 duplicates (0, 0) → FP, P 1/2.
    /// The box at 50 is never found. Envelope: 1 on (0, 1/3], 2/3 on (1/3, 2/3].
    /// AP = 1/3·1 + 1/3·2/3 = 5/9.
    #[test]
    fn ap_by_hand() {
        let truth = vec![vec![b(0.0, 1.0), b(50.0, 1.0)], vec![b(0.0, 1.0)]];
        let dets = vec![
            vec![b(1.0, 0.9), b(100.0, 0.8), b(0.0, 0.6)],
            vec![b(2.0, 0.7)],
        ];
        let ap = average_precision(&dets, &truth, 0.5);
        assert!((ap - 5.0 / 9.0).abs() < 1e-9, "{ap}");
        // Perfect detections: 1; none: 0.
        assert!((average_precision(&truth, &truth, 0.5) - 1.0).abs() < 1e-9);
        assert_eq!(average_precision(&[vec![], vec![]], &truth, 0.5), 0.0);
    }

    /// The same, with an ignored (too faint) fish at x 100 of image 0: the
    /// 0.8 detection there is skipped. Ranked: 0.9 TP (P 1, R 1/3), 0.7 TP
    /// (P 1, R 2/3), 0.6 FP (P 2/3). AP = 2/3 · 1 = 2/3. A duplicate on an
    /// ignored fish is skipped too; a detection on nothing stays false.
    #[test]
    fn ignored_fish_are_neither_found_nor_false() {
        let truth = vec![vec![b(0.0, 1.0), b(50.0, 1.0)], vec![b(0.0, 1.0)]];
        let ignore = vec![vec![b(100.0, 1.0)], vec![]];
        let dets = vec![
            vec![b(1.0, 0.9), b(100.0, 0.8), b(101.0, 0.75), b(0.0, 0.6)],
            vec![b(2.0, 0.7)],
        ];
        let ap = average_precision_ignoring(&dets, &truth, &ignore, 0.5);
        assert!((ap - 2.0 / 3.0).abs() < 1e-9, "{ap}");
        let dets = vec![vec![b(1.0, 0.9), b(200.0, 0.8)], vec![b(2.0, 0.7)]];
        let ap = average_precision_ignoring(&dets, &truth, &ignore, 0.5);
        // 0.9 TP (1, 1/3), 0.8 FP (1/2), 0.7 TP (2/3, 2/3): 1/3 + 1/3 · 2/3 = 5/9.
        assert!((ap - 5.0 / 9.0).abs() < 1e-9, "{ap}");
    }
}
