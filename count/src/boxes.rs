//! Detections, IoU, the edge rule and one NMS over all windows (§4.4.2).

use crate::windows::Window;
use serde::Serialize;

/// A detection in pixels: `[x0, y0, x1, y1]` and a confidence in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Detection {
    pub x0: f32,
    pub y0: f32,
    pub x1: f32,
    pub y1: f32,
    pub score: f32,
}

impl Detection {
    /// From centre and size.
    pub fn from_centre(cx: f32, cy: f32, w: f32, h: f32, score: f32) -> Self {
        Self {
            x0: cx - w / 2.0,
            y0: cy - h / 2.0,
            x1: cx + w / 2.0,
            y1: cy + h / 2.0,
            score,
        }
    }

    pub fn area(&self) -> f32 {
        (self.x1 - self.x0).max(0.0) * (self.y1 - self.y0).max(0.0)
    }

    /// Shifted by `(dx, dy)` and scaled by `k` about the origin first.
    pub fn scaled_shifted(&self, k: f32, dx: f32, dy: f32) -> Self {
        Self {
            x0: self.x0 * k + dx,
            y0: self.y0 * k + dy,
            x1: self.x1 * k + dx,
            y1: self.y1 * k + dy,
            score: self.score,
        }
    }
}

/// Intersection over union of two boxes (0 when either is empty).
pub fn iou(a: &Detection, b: &Detection) -> f32 {
    let iw = (a.x1.min(b.x1) - a.x0.max(b.x0)).max(0.0);
    let ih = (a.y1.min(b.y1) - a.y0.max(b.y0)).max(0.0);
    let inter = iw * ih;
    let union = a.area() + b.area() - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

/// Greedy NMS: by falling score, keep a box unless it overlaps a kept one
/// by more than `iou_threshold`. Ties keep the earlier box.
pub fn nms(mut dets: Vec<Detection>, iou_threshold: f32) -> Vec<Detection> {
    dets.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut keep: Vec<Detection> = Vec::with_capacity(dets.len());
    for d in dets {
        if keep.iter().all(|k| iou(k, &d) <= iou_threshold) {
            keep.push(d);
        }
    }
    keep
}

/// Whether a detection (frame pixels) of window `w` touches one of its edges
/// that lies inside the image (within `margin` px) while being narrower than
/// `step` across that edge. With windows at most `step` apart and `2·step`
/// wide, such a fish lies whole inside the neighbouring window, whose own
/// detection counts it; the cut one is dropped before the NMS, which could
/// not merge the two (a third of a fish has an IoU of a third with it).
pub fn cut_by_inner_edge(
    d: &Detection,
    w: Window,
    window: u32,
    step: u32,
    image: (u32, u32),
    margin: f32,
) -> bool {
    let (x0, y0) = (w.x as f32, w.y as f32);
    let (x1, y1) = (x0 + window as f32, y0 + window as f32);
    let s = step as f32;
    let narrow_x = d.x1 - d.x0 < s;
    let narrow_y = d.y1 - d.y0 < s;
    (narrow_x && w.x > 0 && d.x0 <= x0 + margin)
        || (narrow_x && (x1 as u32) < image.0 && d.x1 >= x1 - margin)
        || (narrow_y && w.y > 0 && d.y0 <= y0 + margin)
        || (narrow_y && (y1 as u32) < image.1 && d.y1 >= y1 - margin)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x0: f32, y0: f32, x1: f32, y1: f32, score: f32) -> Detection {
        Detection {
            x0,
            y0,
            x1,
            y1,
            score,
        }
    }

    /// Two 10 × 10 boxes offset by 5 in x: intersection 50, union 150, IoU 1/3.
    #[test]
    fn iou_by_hand() {
        let a = b(0.0, 0.0, 10.0, 10.0, 1.0);
        assert!((iou(&a, &b(5.0, 0.0, 15.0, 10.0, 1.0)) - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(iou(&a, &a), 1.0);
        assert_eq!(iou(&a, &b(20.0, 0.0, 30.0, 10.0, 1.0)), 0.0);
        // Offset by 2: 80 / 120 = 2/3.
        assert!((iou(&a, &b(2.0, 0.0, 12.0, 10.0, 1.0)) - 2.0 / 3.0).abs() < 1e-6);
    }

    /// Scores 0.9, 0.8, 0.7, 0.6: the 0.8 box overlaps the 0.9 one by 2/3
    /// (suppressed at 0.5), the 0.7 one by 1/3 (kept), the 0.6 one is apart.
    #[test]
    fn nms_by_hand() {
        let dets = vec![
            b(2.0, 0.0, 12.0, 10.0, 0.8),
            b(0.0, 0.0, 10.0, 10.0, 0.9),
            b(5.0, 0.0, 15.0, 10.0, 0.7),
            b(50.0, 50.0, 60.0, 60.0, 0.6),
        ];
        let kept: Vec<f32> = nms(dets.clone(), 0.5).iter().map(|d| d.score).collect();
        assert_eq!(kept, vec![0.9, 0.7, 0.6]);
        // At 0.3 the 1/3 overlap goes too.
        let kept: Vec<f32> = nms(dets, 0.3).iter().map(|d| d.score).collect();
        assert_eq!(kept, vec![0.9, 0.6]);
    }

    /// Window at (208, 0) of a 1280 × 720 frame, 416 wide, step 208: a 40 px
    /// fish at x 206–246 touches its left edge (x = 208 is inside the image):
    /// dropped (the window at 0 holds it whole). The same box in the window at
    /// (0, 0) touches no edge. A 300 px box at the edge is kept (no window
    /// holds it whole); the image's own border never cuts.
    #[test]
    fn edge_rule_by_hand() {
        let img = (1280, 720);
        let cut =
            |fish: &Detection, x, y| cut_by_inner_edge(fish, Window { x, y }, 416, 208, img, 2.0);
        let fish = b(206.0, 100.0, 246.0, 120.0, 0.9);
        assert!(cut(&fish, 208, 0));
        assert!(!cut(&fish, 0, 0));
        let big = b(208.0, 100.0, 508.0, 120.0, 0.9);
        assert!(!cut(&big, 208, 0));
        let at_border = b(0.0, 0.0, 30.0, 20.0, 0.9);
        assert!(!cut(&at_border, 0, 0));
        // Bottom edge of the window at y = 0 is y = 416 < 720: inner.
        let low = b(100.0, 400.0, 130.0, 416.0, 0.9);
        assert!(cut(&low, 0, 0));
        // The flush window at y = 304 ends at 720: the image border.
        let bottom = b(100.0, 700.0, 130.0, 720.0, 0.9);
        assert!(!cut(&bottom, 0, 304));
    }
}
