"""The hand-off report: report.json and report.html (with maps as embedded PNG).

matplotlib through ``Figure`` and the Agg canvas only (no pyplot global state).
"""

from __future__ import annotations

import base64
import html
import io
import json
from typing import Any

import numpy as np

from planner.outputs import json_safe

from ..accuracy import SMITH_VERICAT_RATIO, TEXTBOOK_RATIO_RANGE, AccuracyResult
from .quicklook import QuickLook


def quicklook_dict(q: QuickLook) -> dict[str, Any]:
    big = q.largest
    return {
        "reconstructs": q.reconstructs,
        "verdict": q.verdict(),
        "frames_total": q.n_frames,
        "frames_registered": len(q.registered),
        "registered": list(q.registered),
        "not_registered": [{"name": n, "verified_matches": m} for n, m in sorted(q.unregistered.items())],
        "models": [len(m.registered) for m in q.models],
        "frames_in_georegistered_models": len(q.frames_in_placed_models),
        "points3d": big.num_points if big else 0,
        "mean_track_length": big.mean_track_length if big else None,
        "mean_reprojection_error_px": big.mean_reprojection_error_px if big else None,
        "pairs_matched": q.pairs_matched,
        "max_image_size_px": q.max_image_size_px,
        "max_features": q.max_features,
        "mapper": q.mapper,
        "sift_first_octave": q.sift_first_octave,
        "keypoints_per_frame_median": float(np.median(list(q.keypoints.values()))) if q.keypoints else None,
        "timings_s": q.timings_s,
        "georegistration": q.georegistration.as_dict() if q.georegistration else None,
        "check_vs_reconstruction": q.comparison.as_dict() if q.comparison else None,
        "messages": list(q.messages),
    }


def accuracy_dict(
    result: AccuracyResult, distances: list[dict[str, Any]], notes: tuple[str, ...]
) -> dict[str, Any]:
    return result.as_dict() | {"check_distances": distances, "notes": [*notes, *result.warnings]}


def distances_text(distances: list[dict[str, Any]]) -> str:
    """The distances between check points beside the surveyed ones, as plain text."""
    if not distances:
        return ""
    lines = ["distances between check points (horizontal): surveyed m, model m, model - surveyed m"]
    for d in distances:
        lines.append(
            f"  {d['a']}-{d['b']:<8} {d['surveyed_m']:9.3f} {d['model_m']:9.3f} {d['difference_m']:+9.3f}"
        )
    return "\n".join(lines)


def _f(value: float | None, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def write_json(data: dict[str, Any]) -> str:
    return json.dumps(json_safe(data), indent=2, allow_nan=False)


def _png(fig: Any) -> str:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def comparison_png(q: QuickLook) -> str | None:
    from matplotlib.figure import Figure

    c = q.comparison
    if c is None:
        return None
    fig = Figure(figsize=(10, 4.6))
    extent = (c.extent_xy_m[0], c.extent_xy_m[2], c.extent_xy_m[1], c.extent_xy_m[3])
    a1 = fig.add_subplot(1, 2, 1)
    im1 = a1.imshow(c.view_count, extent=extent, cmap="viridis", interpolation="nearest")
    a1.set_title(f"check: views per {c.cell_m:g} m cell (fewest)")
    fig.colorbar(im1, ax=a1, shrink=0.8)
    a2 = fig.add_subplot(1, 2, 2)
    im2 = a2.imshow(np.log10(1 + c.point_count), extent=extent, cmap="magma", interpolation="nearest")
    empty = (c.view_count >= 2) & (c.point_count == 0)
    if empty.any():
        a2.contour(empty.astype(float), levels=[0.5], colors="cyan", extent=extent, origin="upper")
    a2.set_title("reconstruction: log10(1 + sparse points); cyan: covered, empty")
    fig.colorbar(im2, ax=a2, shrink=0.8)
    for a in (a1, a2):
        a.set_xlabel("east, m")
        a.set_ylabel("north, m")
    return _png(fig)


def _table(headers: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def accuracy_html(acc: dict[str, Any]) -> str:
    rows = []
    for key in ("control", "check"):
        r = acc.get(key)
        if r:
            rows.append(
                [
                    key,
                    r["n_points"],
                    f"{r['rmse_x_m']:.3f}",
                    f"{r['rmse_y_m']:.3f}",
                    _f(r["rmse_z_m"]),
                    f"{r['rmse_horizontal_m']:.3f}",
                    _f(r["rmse_total_m"]),
                    f"{r['rmse_image_px']:.2f}",
                    f"{r['rmse_marks_px']:.2f}",
                    f"{r['range_m']:.1f}",
                    r["rmse_to_range"],
                ]
            )
    rows.append(
        [
            "textbook (Table 3-2)",
            9,
            *[""] * 7,
            "75.6",
            f"1:{TEXTBOOK_RATIO_RANGE[0]:.0f} to 1:{TEXTBOOK_RATIO_RANGE[1]:.0f}",
        ]
    )
    rows.append(
        [
            "Smith and Vericat (2015), mean of 50",
            *[""] * 9,
            f"1:{SMITH_VERICAT_RATIO:.0f}",
        ]
    )
    out = "<h2>Accuracy at ground control and check points</h2>"
    out += f"<p>Fit: {html.escape(str(acc.get('fit', '')))}.</p>"
    if not acc.get("heights_known", True):
        out += (
            "<p class='note'>Z is not measurable: the surveyed heights are unknown (all 0.0); "
            "RMSE:range is on the horizontal RMSE.</p>"
        )
    out += _table(
        [
            "points",
            "n",
            "RMSE X m",
            "RMSE Y m",
            "RMSE Z m",
            "horizontal m",
            "total m",
            "image px",
            "marks px",
            "range m",
            "RMSE:range",
        ],
        rows,
    )
    out += _table(
        [
            "point",
            "role",
            "dX m",
            "dY m",
            "dZ m",
            "left out of the fit, horizontal m",
            "image px",
            "marks px",
            "images",
            "widest ray angle deg",
        ],
        [
            [
                p["name"],
                p["role"],
                f"{p['dx_m']:.3f}",
                f"{p['dy_m']:.3f}",
                _f(p["dz_m"]),
                _f(p.get("left_out_horizontal_m")),
                f"{p['image_rmse_px']:.2f}",
                f"{p['marks_rmse_px']:.2f}",
                p["n_images"],
                f"{p['widest_angle_deg']:.1f}",
            ]
            for p in acc["points"]
        ],
    )
    if acc.get("check_distances"):
        out += "<h3>Distances between check points (horizontal)</h3>" + _table(
            ["a", "b", "surveyed m", "model m", "difference m"],
            [
                [d["a"], d["b"], f"{d['surveyed_m']:.3f}", f"{d['model_m']:.3f}", f"{d['difference_m']:+.3f}"]
                for d in acc["check_distances"]
            ],
        )
    for u in acc.get("unused_points", []):
        out += f"<p>Not used: {html.escape(u['name'])}: {html.escape(u['reason'])}</p>"
    for note in acc.get("notes", []):
        out += f"<p class='note'>{html.escape(note)}</p>"
    return out


def report_html(data: dict[str, Any], q: QuickLook | None) -> str:
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>sfap handoff</title><style>"
        "body{font-family:sans-serif;max-width:1100px;margin:1em auto}"
        "table{border-collapse:collapse;margin:.6em 0}"
        "td,th{border:1px solid #bbb;padding:2px 6px;text-align:right}.bad{color:#b00;font-weight:bold}"
        ".good{color:#060;font-weight:bold}</style></head><body><h1>Hand-off report</h1>"
    ]
    project = data.get("project", {})
    parts.append(
        f"<p>{project.get('images')} frames, {project.get('positioned')} with a position; "
        f"{project.get('pairs', {}).get('count')} pairs of "
        f"{project.get('pairs', {}).get('possible')} possible. "
        f"Local frame: <code>{html.escape(str(project.get('local_frame', {}).get('proj')))}</code></p>"
    )
    for note in project.get("notes", []):
        parts.append(f"<p class='note'>{html.escape(note)}</p>")
    ql = data.get("quicklook")
    if ql:
        cls = "good" if ql["reconstructs"] else "bad"
        parts.append(f"<p class='{cls}'>{html.escape(ql['verdict'])}</p>")
        rows = [
            ["frames registered", f"{ql['frames_registered']} of {ql['frames_total']}"],
            ["models (frames each)", ", ".join(map(str, ql["models"])) or "none"],
            ["3D points", ql["points3d"]],
            ["mean track length", f"{ql['mean_track_length']:.2f}" if ql["mean_track_length"] else "-"],
            [
                "mean reprojection error, px",
                f"{ql['mean_reprojection_error_px']:.2f}" if ql["mean_reprojection_error_px"] else "-",
            ],
            ["features on frames of, px", ql["max_image_size_px"]],
        ]
        geo = ql.get("georegistration")
        if geo:
            rows += [
                ["camera residuals to GPS, RMSE horizontal m", f"{geo['camera_rmse_horizontal_m']:.2f}"],
                ["camera residuals to GPS, RMSE vertical m", f"{geo['camera_rmse_vertical_m']:.2f}"],
                ["camera residuals to GPS, RMSE total m", f"{geo['camera_rmse_total_m']:.2f}"],
            ]
        rows += [[f"time {k[:-2]}, s", f"{v:.1f}"] for k, v in ql["timings_s"].items()]
        parts.append(_table(["", ""], rows))
        if ql["not_registered"]:
            parts.append("<h2>Frames not registered</h2>")
            parts.append(
                _table(
                    ["frame", "verified matches"],
                    [[r["name"], r["verified_matches"]] for r in ql["not_registered"]],
                )
            )
        cmp_ = ql.get("check_vs_reconstruction")
        if cmp_:
            parts.append(
                "<h2>What the check predicted against what reconstructed</h2>"
                f"<p>{cmp_['covered_cells']} cells of {cmp_['cell_m']:g} m seen by two frames or more; "
                f"{cmp_['covered_but_empty_cells']} of them "
                f"({cmp_['covered_but_empty_area_m2']:.0f} m2) have no "
                f"sparse point. The check's gaps: {cmp_['check_gap_area_m2']:.0f} m2.</p>"
            )
            png = comparison_png(q) if q is not None else None
            if png:
                parts.append(f"<img alt='check vs reconstruction' src='data:image/png;base64,{png}'>")
    acc = data.get("accuracy")
    if acc:
        parts.append(accuracy_html(acc))
    parts.append("</body></html>")
    return "\n".join(parts)
