"""The COLMAP project: ``database.db`` (cameras, images, pose priors), ``pairs.txt`` (the pairs
COLMAP's matches importer reads), ``images`` (a link to the image folder), ``project.json``
(the local frame the priors are in, the cameras, the pairs' provenance) and ``README.txt``
(the COLMAP commands that run it)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from . import colmap_adapter as colmap
from .block import proj_string
from .prepare import Prepared

DATABASE = "database.db"
PAIRS = "pairs.txt"
PROJECT = "project.json"

_README = """COLMAP project written by sfap handoff.

database.db   cameras (one per camera model: focal length in pixels, principal point at the
              centre), one image per frame, a pose prior per positioned frame (CARTESIAN, in the
              local frame named in project.json, covariance from the tags' accuracy)
pairs.txt     the image pairs to match ({n_pairs} pairs of {n_all} possible): {pairs_from}
images        the image folder ({image_dir})

Run it with COLMAP's command line:

  colmap feature_extractor --database_path database.db --image_path images \\
      --FeatureExtraction.max_image_size 2000
  colmap matches_importer --database_path database.db --match_list_path pairs.txt --match_type pairs
  mkdir -p sparse && colmap mapper --database_path database.db --image_path images --output_path sparse

or `sfap handoff IMAGES --to colmap --run -o WORK`, which also reports the result.
"""


def project_info(prepared: Prepared) -> dict[str, Any]:
    block, pairs = prepared.block, prepared.pairs
    n = len(block)
    reasons = {r: sum(1 for x in pairs.reason if x == r) for r in sorted(set(pairs.reason))}
    return {
        "images": n,
        "image_dir": str(block.image_dir),
        "positioned": int(block.has_position.sum()),
        "unpositioned": list(block.unpositioned),
        "local_frame": {
            "proj": proj_string(block.frame) if block.frame is not None else None,
            "wkt": block.frame.crs.to_wkt() if block.frame is not None else None,
            "z": f"camera altitude ({block.alt_reference.value})" if block.alt_reference else None,
            "description": "x metres east, y metres north of the origin (transverse Mercator, scale 1)",
        },
        "prior_sigma_source": block.sigma_source,
        "ground": prepared.ground_description,
        "cameras": [
            i.as_dict() | {"images": int((block.camera_index == c).sum())}
            for c, i in enumerate(block.intrinsics)
        ],
        "pairs": {"count": len(pairs), "possible": n * (n - 1) // 2, "by_reason": reasons},
        "notes": list(block.notes) + list(pairs.notes),
        "engine": f"pycolmap {colmap.version()}",
    }


def write_colmap_project(prepared: Prepared, folder: Path) -> dict[str, Any]:
    """Write the project into ``folder`` (an empty staging folder); returns project.json's data."""
    block = prepared.block
    folder.mkdir(parents=True, exist_ok=True)
    cameras = [
        colmap.CameraSpec(
            width_px=i.width_px, height_px=i.height_px, focal_px=i.focal_px, principal_xy_px=i.principal_xy_px
        )
        for i in block.intrinsics
    ]
    by_camera = [
        [block.names[k] for k in np.flatnonzero(block.camera_index == c)] for c in range(len(cameras))
    ]
    priors = [
        colmap.PriorSpec(
            name=block.names[k],
            position_m=(
                float(block.position_m[k, 0]),
                float(block.position_m[k, 1]),
                float(block.position_m[k, 2]),
            ),
            sigma_xy_m=float(block.sigma_xy_m[k]),
            sigma_z_m=float(block.sigma_z_m[k]),
        )
        for k in np.flatnonzero(block.has_position)
    ]
    colmap.write_database(folder / DATABASE, block.image_dir, cameras, by_camera, priors)
    (folder / PAIRS).write_text(prepared.pairs.text(block), encoding="utf-8")
    os.symlink(block.image_dir, folder / "images", target_is_directory=True)
    info = project_info(prepared)
    (folder / PROJECT).write_text(json.dumps(info, indent=2), encoding="utf-8")
    (folder / "README.txt").write_text(
        _README.format(
            n_pairs=len(prepared.pairs),
            n_all=info["pairs"]["possible"],
            image_dir=block.image_dir,
            pairs_from="from the frames' ground footprints"
            if prepared.pairs.footprints
            else "from the camera positions (no ground)"
            if prepared.block.has_position.any()
            else "every pair (no positions)",
        ),
        encoding="utf-8",
    )
    return info
