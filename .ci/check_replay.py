"""Judge a replay as a user would see it in Chromium (issue 16).

    python3 .ci/check_replay.py DIR

DIR holds what `.ci/browser/replay.mjs` left (result.json, a.png, b.png taken a
few seconds of playback apart) and the GIF `deepfoids replay --gif` wrote
(clip.gif). Asserts: the page reported no console or page errors and fetched
nothing from the network; the clock ran; the 3D view is not blank; it shows
fish, and the fish pixels moved between the screenshots; the P/M cursor moved
to where the page says it is; clicking a fish follows the fish under the
pointer and shows its speed, depth and reward terms, Esc lets go; the GIF has
one frame per recorded frame.
"""

import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image

out = Path(sys.argv[1])
shots = out / "shots"
r = json.loads((shots / "result.json").read_text())
problems = []


def check(ok, what):
    if not ok:
        problems.append(what)


check("driver_error" not in r, f"the browser driver failed: {r.get('driver_error')}")
check(not r["console_errors"], f"console errors: {r['console_errors']}")
check(not r["page_errors"], f"page errors: {r['page_errors']}")
remote = [u for u in r["requests"] if not u.startswith(("file:", "blob:", "data:"))]
check(not remote, f"the page fetched from the network: {remote}")
a, b = r.get("a"), r.get("b")
if problems or a is None or b is None:
    sys.exit("replay check failed:\n  " + "\n  ".join(problems or ["no screenshots taken"]))
check(a["error"] is None and b["error"] is None, f"the viewer reported: {a['error'] or b['error']}")
check(b["time"] > a["time"] + 1.0, f"the clock did not run: t = {a['time']:.2f} s, then {b['time']:.2f} s")


def rect(img, box):
    x, y, w, h = (int(round(box[k])) for k in ("x", "y", "width", "height"))
    return img[y : y + h, x : x + w]


def fish_mask(view, state):
    """Saturated, lit pixels: fish (Okabe-Ito colours under light). The water is
    dark, the net lines grey-blue and faint; the legend panel is blanked out."""
    mx = view.max(axis=2)
    mn = view.min(axis=2)
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1), 0)
    mask = (sat > 0.45) & (mx > 100)
    lg, vw = state["legend"], state["view"]
    x0, y0 = int(lg["x"] - vw["x"]), int(lg["y"] - vw["y"])
    mask[max(0, y0) : y0 + int(lg["height"]) + 1, max(0, x0) : x0 + int(lg["width"]) + 1] = False
    return mask


imgs = {}
for name, state in (("a", a), ("b", b)):
    img = np.asarray(Image.open(shots / f"{name}.png").convert("RGB")).astype(np.int32)
    view = rect(img, state["view"])
    colours = len(np.unique(view.reshape(-1, 3), axis=0))
    spread = view.reshape(-1, 3).std(axis=0).max()
    check(spread > 10 and colours > 500, f"{name}.png: the 3D view looks blank (std {spread:.1f}, {colours} colours)")
    mask = fish_mask(view, state)
    check(mask.sum() > 5000, f"{name}.png: only {mask.sum()} fish pixels in the view")
    # The P/M cursor: the chart column with the most near-black pixels.
    chart = rect(img, state["chart"])
    dark = (chart.max(axis=2) < 60).sum(axis=0)
    col = int(dark.argmax())
    check(dark[col] > 0.5 * chart.shape[0], f"{name}.png: no P/M cursor line in the chart (best column {col}: {dark[col]} px)")
    check(abs(col - state["cursor_x"]) <= 3, f"{name}.png: the cursor is drawn at x = {col} but the page put it at {state['cursor_x']:.1f}")
    imgs[name] = (mask, col)

(ma, ca), (mb, cb) = imgs["a"], imgs["b"]
moved = (ma ^ mb).sum() / max(1, (ma | mb).sum())
check(moved > 0.3, f"the fish did not move between the screenshots ({moved:.0%} of fish pixels changed)")
check(cb - ca > 20, f"the P/M cursor did not move: x = {ca}, then {cb}")

click = r.get("click")
check(click is not None, "no fish found to click in the top view")
if click:
    sel = click["selected"]
    check(sel is not None and click["info_shown"], f"clicking fish {click['target']['i']} selected nothing: {click}")
    if sel is not None:
        t = click["target"]
        check(sel in t["near"], f"the click at ({t['x']:.0f}, {t['y']:.0f}) followed fish {sel}, not one drawn there ({t['near']})")
        check("speed" in click["info_text"] and "depth" in click["info_text"] and "neighbour_distance" in click["info_text"], f"the fish panel lacks speed, depth or reward terms: {click['info_text']}")
    check(click.get("after_escape", 0) is None, "Esc did not stop following")

gif = Image.open(out / "clip.gif")
check(gif.n_frames == a["frames"], f"clip.gif has {gif.n_frames} frames, the replay {a['frames']}")

if problems:
    sys.exit("replay check failed:\n  " + "\n  ".join(problems))
print(
    f"replay check passed: first frame after {r['first_frame_seconds']:.1f} s, "
    f"t {a['time']:.1f} → {b['time']:.1f} s, {ma.sum()} / {mb.sum()} fish pixels, {moved:.0%} changed, "
    f"cursor x {ca} → {cb}, {a['fish']} fish × {a['frames']} frames, "
    f"{b['fps']:.1f} frames/s drawn (software WebGL: {r.get('software_gl')}), clip.gif {gif.n_frames} frames"
)
