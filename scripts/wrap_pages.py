"""Write one Meshcat page a category: a generated object of each category wrapped by
Algorithm 1 (models/config.yaml's arm, planes and wrap settings), saved as a self-contained
HTML page (the animation, the contacts as pins, a title and legend) any browser replays.

The object of a category is the first of a one-object-a-category dataset generated with
--seed; its wrap is on the first plane that gives a complete wrap, else the one whose tip
turned furthest (viz.plots.choose_wrap). Prints one JSON line a page (category, file, size).

    python scripts/wrap_pages.py --out docs/pages                      # all ten
    python scripts/wrap_pages.py --out docs/pages --categories apple,mug
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from drake_continuum import (
    WrapScene,
    enumerate_planes,
    generate_dataset,
    load_config,
    load_manifest,
)
from drake_continuum.objects.generators import CATEGORY_COUNTS
from drake_continuum.viz.meshcat import make_meshcat, show_wrap, wrap_title
from drake_continuum.viz.plots import choose_wrap


def write_pages(out: Path, categories: list[str], seed: int = 0) -> list[dict]:
    """Generate one object of each category, wrap it and write <out>/<category>.html."""
    cfg = load_config()
    arm = cfg.arm()
    planes = enumerate_planes(arm.base_position, cfg.alpha_deg, cfg.both_directions)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        generate_dataset(tmp, seed=seed, counts={c: 1 for c in categories}, workers=1,
                         progress=False)
        dataset = load_manifest(tmp)
        for category in categories:
            entry = dataset.by_category(category)[0]
            mesh = entry.load()
            result = choose_wrap(WrapScene(arm, mesh), planes, cfg.wrap)
            page = out / f"{category}.html"
            label = planes[result.plane_index].label
            show_wrap(arm.with_base(rotation=result.base_rotation), mesh, result.configs,
                      contacts=result.contacts, meshcat=make_meshcat(), html_path=page,
                      title=wrap_title(f"{entry.id} (seed {seed})", label, result))
            rows.append({"category": category, "object": entry.id, "plane": label,
                         "status": result.status, "contacts": len(result.contacts),
                         "page": str(page), "bytes": page.stat().st_size})
            print(json.dumps(rows[-1]), flush=True)
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder for the pages, e.g. docs/pages")
    parser.add_argument("--categories", default=",".join(CATEGORY_COUNTS),
                        help="comma-separated categories (default: all ten)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the generated objects (default: 0)")
    args = parser.parse_args()
    categories = [c for c in args.categories.split(",") if c]
    unknown = sorted(set(categories) - set(CATEGORY_COUNTS))
    if unknown:
        print(f"--categories: unknown {', '.join(unknown)}; known: "
              f"{', '.join(CATEGORY_COUNTS)}", file=sys.stderr)
        return 2
    write_pages(Path(args.out), categories, args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
