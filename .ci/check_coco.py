"""Load the COCO file written by `deepfoids render` (tests/render.rs leaves one
at target/render-check) with pycocotools and check boxes, areas and masks."""
import json
import sys

import numpy as np
from pycocotools.coco import COCO
from PIL import Image

root = sys.argv[1] if len(sys.argv) > 1 else "target/render-check"
coco = COCO(f"{root}/annotations.json")
anns = coco.loadAnns(coco.getAnnIds())
assert anns, "no annotations"
assert [c["name"] for c in coco.loadCats(coco.getCatIds())] == ["seabream"]
for a in anns:
    img = coco.loadImgs(a["image_id"])[0]
    m = coco.annToMask(a)
    assert m.shape == (img["height"], img["width"])
    assert int(m.sum()) == a["area"], (a["id"], int(m.sum()), a["area"])
    # The RLE equals the 16-bit instance mask's pixels of this fish.
    ids = np.array(Image.open(f"{root}/masks/" + img["file_name"].split("/")[-1].rsplit(".", 1)[0] + ".png"))
    assert np.array_equal(m.astype(bool), ids == a["fish_id"] + 1), a["id"]
    x, y, w, h = a["bbox"]
    ys, xs = np.nonzero(m)
    assert (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1) == (x, y, x + w, y + h), a["id"]
print(f"COCO check passed: {len(anns)} annotations in {len(coco.getImgIds())} images")
