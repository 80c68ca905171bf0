"""The built-in camera database: every entry real and plausible, the textbook's and QGC's numbers,
EXIF matching against real images, and cameras built from mission-spec keys."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import exifread
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shared_data import SHARED_DATA, needs

from planner.camera import Camera, Orientation
from planner.camera_db import (
    MAPPING_KEYS,
    camera_from_mapping,
    get_camera,
    load_cameras,
    match_exif,
    parse_cameras,
)
from planner.camera_figures import camera_figures
from planner.errors import CameraError, InputError

SEQUOIA_DIR = SHARED_DATA / "garfield_rgb"

#: Cameras the issue names; each must be in the database under these ids.
REQUIRED_IDS = (
    "dji-phantom-4-pro",
    "dji-phantom-4-pro-v2",
    "dji-phantom-4-rtk",
    "dji-mavic-3-enterprise",
    "dji-mavic-3-multispectral-rgb",
    "dji-zenmuse-p1-24mm",
    "dji-zenmuse-p1-35mm",
    "dji-mini-4-pro",
    "dji-mini-3-pro",
    "dji-mavic-2-pro",
    "dji-air-2s",
    "dji-matrice-4e-wide",
    "dji-zenmuse-l2-rgb",
    "sony-a6000-16mm",
    "sony-a6000-20mm",
    "sony-a7r-iv-35mm",
    "sony-rx1r-ii",
    "sony-a5100-16mm",
    "sony-qx1-20mm",
    "sony-umc-r10c-16mm",
    "parrot-sequoia-rgb",
    "parrot-anafi",
    "micasense-rededge-mx",
    "micasense-altum",
    "sensefly-soda",
    "autel-evo-ii-pro-6k",
    "gopro-hero9-black-linear",
    "canon-eos-350d-20mm",
)

CAMERAS = load_cameras()
CAMERA_IDS = sorted(CAMERAS)


def _real_entry_text(camera_id: str) -> str:
    """The TOML text of one real database entry, for building broken variants of it."""
    text = (Path(__file__).parents[2] / "planner" / "data" / "cameras.toml").read_text()
    blocks = text.split("[[camera]]")
    (block,) = [b for b in blocks if f'id = "{camera_id}"' in b]
    return "[[camera]]" + block


# --- the database as a whole -------------------------------------------------------------------


def test_database_holds_at_least_80_cameras_including_the_named_ones() -> None:
    assert len(CAMERAS) >= 80
    missing = [camera_id for camera_id in REQUIRED_IDS if camera_id not in CAMERAS]
    assert missing == []


@pytest.mark.parametrize("camera_id", CAMERA_IDS)
def test_every_entry_is_complete_and_plausible(camera_id: str) -> None:
    camera = CAMERAS[camera_id]
    assert isinstance(camera, Camera)
    assert camera.id == camera_id
    assert re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", camera_id)
    assert camera.name and camera.exif_make and camera.exif_model
    assert len(camera.source) > 20  # a real citation, not a placeholder
    # Pitch from sensor size and pixels: the same on both axes, inside what sensors are made with.
    pitch_x_um = camera.pixel_pitch_x_mm * 1000
    pitch_y_um = camera.pixel_pitch_y_mm * 1000
    assert 1.0 <= pitch_x_um <= 10.0
    assert pitch_x_um == pytest.approx(pitch_y_um, rel=0.03)
    # The image's aspect ratio is the sensor's.
    assert camera.image_width_px / camera.image_height_px == pytest.approx(
        camera.sensor_width_mm / camera.sensor_height_mm, rel=0.03
    )
    # Landscape convention of planner.camera: x is the long side.
    assert camera.image_width_px >= camera.image_height_px
    # A real focal length, not a 35 mm equivalent: survey lenses are 19-60 mm equivalent,
    # i.e. a diagonal field of view between about 40 and 100 degrees.
    figures = camera_figures(camera)
    assert 18.0 <= figures.focal_length_35mm_equiv_mm <= 60.0
    assert 40.0 <= figures.fov_diagonal_deg <= 100.0
    assert 0.3 <= camera.min_trigger_interval_s <= 5.0
    assert camera.shutter_s is None or 1e-4 <= camera.shutter_s <= 1 / 100


def test_published_pixel_pitches_agree_with_sensor_size_over_pixels() -> None:
    # Cross-check with pitches published independently of the sensor sizes in the file.
    published_um = {
        "dji-zenmuse-p1-35mm": 4.4,  # DJI P1 specs
        "dji-air-2s": 2.4,  # DJI Air 2S specs
        "dji-mini-4-pro": 2.4,  # DJI: 2.4 um 4-in-1 pixels
        "micasense-rededge-mx": 1000 / 266.666667,  # EXIF FocalPlaneResolution, MicaSense tests
        "parrot-sequoia-rgb": 1.34,  # EXIF FocalPlaneResolution of the garfield images
        "canon-eos-350d-20mm": 6.4,  # Aber et al. 2019, ch. 3
    }
    for camera_id, pitch_um in published_um.items():
        camera = CAMERAS[camera_id]
        assert camera.pixel_pitch_x_mm * 1000 == pytest.approx(pitch_um, rel=0.03), camera_id


def test_load_cameras_returns_a_copy_of_a_cached_database() -> None:
    first = load_cameras()
    first.pop("canon-eos-350d-20mm")
    second = load_cameras()
    assert "canon-eos-350d-20mm" in second
    assert second["dji-air-2s"] is first["dji-air-2s"]  # parsed once


# --- published numbers ---------------------------------------------------------------------------


def test_textbook_camera_gives_2_42_cm_at_75_6_m() -> None:
    # Aber et al. (2019) Eq. 3-4 with the chapter's camera: 6.4 um x 75.6 m / 20 mm = 2.419 cm.
    camera = get_camera("canon-eos-350d-20mm")
    assert (camera.image_width_px, camera.image_height_px) == (3456, 2304)
    assert (camera.sensor_width_mm, camera.sensor_height_mm) == (22.2, 14.8)
    assert camera.focal_length_mm == 20.0
    textbook_gsd_cm = 6.4e-6 * 75.6 / 0.020 * 100
    assert textbook_gsd_cm == pytest.approx(2.419, abs=5e-4)
    assert camera.gsd_cm(75.6) == pytest.approx(2.42, abs=0.01)
    # 22.2 mm / 3456 px = 6.424 um, the textbook rounds to 6.4 um: 0.4 % apart.
    assert camera.gsd_cm(75.6) == pytest.approx(textbook_gsd_cm, rel=0.005)
    # The chapter's flying heights 60-82 m give its GSD range of 1.9-2.6 cm.
    assert camera.gsd_cm(60.0) == pytest.approx(1.9, abs=0.05)
    assert camera.gsd_cm(82.0) == pytest.approx(2.6, abs=0.05)


def _qgc_gsd_cm(camera: Camera, height_m: float) -> float:
    """QGroundControl CameraCalc: GSD from the sensor width only."""
    return 100.0 * height_m * camera.sensor_width_mm / (camera.image_width_px * camera.focal_length_mm)


def _qgc_height_m(camera: Camera, gsd_cm: float) -> float:
    return gsd_cm * camera.image_width_px * camera.focal_length_mm / (100.0 * camera.sensor_width_mm)


def test_qgc_formulas_match_for_every_square_pitch_camera() -> None:
    square = [camera for camera in CAMERAS.values() if camera.pitch_is_square]
    assert len(square) >= 12  # the comparison covers most of the database
    for camera in square:
        for height_m in (30.0, 75.6, 120.0):
            assert camera.gsd_cm(height_m) == pytest.approx(_qgc_gsd_cm(camera, height_m), rel=1e-3), (
                camera.id
            )
        assert camera.height_for_gsd_m(2.0) == pytest.approx(_qgc_height_m(camera, 2.0), rel=1e-3), camera.id
    for camera in CAMERAS.values():
        # Along the image width the two agree exactly for every camera.
        assert camera.gsd_x_cm(100.0) == pytest.approx(_qgc_gsd_cm(camera, 100.0), rel=1e-12)


@settings(max_examples=200, deadline=None)
@given(
    camera_id=st.sampled_from(CAMERA_IDS),
    gsd_cm=st.floats(min_value=0.2, max_value=30.0, allow_nan=False),
)
def test_gsd_height_round_trip(camera_id: str, gsd_cm: float) -> None:
    camera = CAMERAS[camera_id]
    height_m = camera.height_for_gsd_m(gsd_cm)
    assert height_m > 0
    assert camera.gsd_cm(height_m) == pytest.approx(gsd_cm, rel=1e-9)
    assert camera.height_for_gsd_m(camera.gsd_cm(height_m)) == pytest.approx(height_m, rel=1e-9)
    # The guaranteed GSD is the coarser axis: neither axis is coarser than asked.
    assert max(camera.gsd_x_cm(height_m), camera.gsd_y_cm(height_m)) <= gsd_cm * (1 + 1e-9)


# --- EXIF matching ------------------------------------------------------------------------------


def _ratio(tags: dict[str, Any], name: str) -> float:
    """An EXIF rational tag as a float (exifread's Ratio is a Fraction)."""
    return float(tags[name].values[0])


@needs("garfield_rgb")
def test_sequoia_images_match_their_entry_through_their_exif() -> None:
    images = sorted(SEQUOIA_DIR.glob("*.JPG"))
    assert len(images) >= 20
    entry = get_camera("parrot-sequoia-rgb")
    for image in images:
        with image.open("rb") as handle:
            tags = exifread.process_file(handle, details=False)
        make = str(tags["Image Make"]).strip()
        model = str(tags["Image Model"]).strip()
        focal_mm = _ratio(tags, "EXIF FocalLength")
        width_px = int(str(tags["EXIF ExifImageWidth"]))
        height_px = int(str(tags["EXIF ExifImageLength"]))
        assert match_exif(make, model, focal_mm, width_px, height_px) is entry, image.name
        # FocalPlaneResolutionUnit 4 = millimetres: the sensor size the camera states.
        assert int(str(tags["EXIF FocalPlaneResolutionUnit"])) == 4
        px_per_mm = _ratio(tags, "EXIF FocalPlaneXResolution")
        assert width_px / px_per_mm == pytest.approx(entry.sensor_width_mm, rel=1e-3)
        assert height_px / _ratio(tags, "EXIF FocalPlaneYResolution") == pytest.approx(
            entry.sensor_height_mm, rel=1e-3
        )
        assert focal_mm == pytest.approx(entry.focal_length_mm, rel=1e-3)


def test_match_exif_ignores_case_spaces_and_orientation() -> None:
    p4p = get_camera("dji-phantom-4-pro")
    assert match_exif("dji", " fc6310 ", 8.8, 5472, 3648) is p4p
    assert match_exif("DJI", "FC6310", 8.8, 3648, 5472) is p4p  # portrait
    assert match_exif(None, "FC6310", None, None, None) is p4p
    assert match_exif("DJI", "FC6310S", 8.8, 5472, 3648) is get_camera("dji-phantom-4-pro-v2")
    assert match_exif("Hasselblad", "L1D-20c", 10.3, 5472, 3648) is get_camera("dji-mavic-2-pro")


def test_match_exif_rejects_what_does_not_fit() -> None:
    assert match_exif("DJI", "FC6310", 12.0, 5472, 3648) is None  # focal > 5 % off
    assert match_exif("DJI", "FC6310", 8.8, 4864, 3648) is None  # 4:3 crop mode: other geometry
    assert match_exif("Canon", "FC6310", 8.8, 5472, 3648) is None  # wrong make
    assert match_exif("DJI", "FC9999", 8.8, 5472, 3648) is None
    assert match_exif("DJI", None, 8.8, 5472, 3648) is None
    assert match_exif("DJI", "FC6310", 8.8 * 1.049, 5472, 3648) is not None  # inside 5 %


def test_match_exif_picks_the_lens_by_focal_length_or_refuses_to_guess() -> None:
    assert match_exif("DJI", "ZenmuseP1", 35.0, 8192, 5460) is get_camera("dji-zenmuse-p1-35mm")
    assert match_exif("DJI", "ZenmuseP1", 24.0, 8192, 5460) is get_camera("dji-zenmuse-p1-24mm")
    assert match_exif("SONY", "ILCE-6000", 20.0, 6000, 4000) is get_camera("sony-a6000-20mm")
    # No focal length: two lenses fit and their GSDs differ, so no answer.
    assert match_exif("DJI", "ZenmuseP1", None, 8192, 5460) is None


# --- lookups and errors -------------------------------------------------------------------------


def test_unknown_id_lists_the_closest_ids() -> None:
    with pytest.raises(CameraError) as info:
        get_camera("dji-phantom-9")
    message = str(info.value)
    assert "'dji-phantom-9'" in message
    assert "dji-phantom-4" in message
    assert "sfap cameras" in message
    assert isinstance(info.value, InputError) and info.value.exit_code == 2


def test_typo_in_an_id_still_finds_it() -> None:
    with pytest.raises(CameraError, match="sony-a6000-16mm"):
        get_camera("sony-a600-16mm")


# --- cameras from mission-spec keys ------------------------------------------------------------


def test_model_alone_is_the_database_camera() -> None:
    assert camera_from_mapping({"model": "dji-air-2s"}, where="m.toml [camera]") is get_camera("dji-air-2s")


def test_model_with_overrides() -> None:
    base = get_camera("sony-a6000-16mm")
    camera = camera_from_mapping(
        {"model": "sony-a6000-16mm", "shutter_s": 0.0005, "min_trigger_interval_s": 1.5},
        where="m.toml [camera]",
    )
    assert camera.shutter_s == 0.0005
    assert camera.min_trigger_interval_s == 1.5
    assert camera.id == base.id
    assert camera.sensor_width_mm == base.sensor_width_mm
    assert "m.toml [camera]" in camera.source and "shutter_s" in camera.source


def test_custom_camera_from_its_own_numbers() -> None:
    camera = camera_from_mapping(
        {
            "sensor_width_mm": 22.2,
            "sensor_height_mm": 14.8,
            "image_width_px": 3456,
            "image_height_px": 2304,
            "focal_length_mm": 20,
            "pixel_pitch_um": 6.4,
        },
        where="m.toml [camera]",
    )
    assert camera.id == "custom"
    assert camera.source == "custom camera in m.toml [camera]"
    reference = get_camera("canon-eos-350d-20mm")
    assert camera.gsd_cm(75.6) == pytest.approx(reference.gsd_cm(75.6), rel=1e-12)
    assert camera.min_trigger_interval_s == 2.0  # Camera's default
    assert camera.shutter_s is None


def test_custom_camera_keeps_its_name_and_source() -> None:
    camera = camera_from_mapping(
        {
            "name": "Ricoh GR II",
            "source": "Ricoh GR II spec sheet",
            "sensor_width_mm": 23.7,
            "sensor_height_mm": 15.7,
            "image_width_px": 4928,
            "image_height_px": 3264,
            "focal_length_mm": 18.3,
            "shutter_s": 0.001,
        },
        where="m.toml [camera]",
    )
    assert (camera.name, camera.source, camera.shutter_s) == (
        "Ricoh GR II",
        "Ricoh GR II spec sheet",
        0.001,
    )


def test_custom_camera_may_have_non_square_pixels() -> None:
    # The planner handles a non-square pitch (the point of per-axis GSD); only the database,
    # which holds real cameras, insists on square pixels.
    camera = camera_from_mapping(
        {
            "sensor_width_mm": 6.4,
            "sensor_height_mm": 4.8,
            "image_width_px": 1920,
            "image_height_px": 1080,
            "focal_length_mm": 4.0,
        },
        where="m.toml [camera]",
    )
    assert not camera.pitch_is_square
    assert camera.gsd_cm(100.0) == pytest.approx(camera.gsd_y_cm(100.0))


def test_unknown_key_is_an_error_listing_the_valid_keys() -> None:
    with pytest.raises(CameraError) as info:
        camera_from_mapping({"model": "dji-air-2s", "focal_mm": 9.0}, where="m.toml [camera]")
    message = str(info.value)
    assert message.startswith("m.toml [camera]")
    assert "'focal_mm'" in message and "focal_length_mm" in message
    for key in MAPPING_KEYS:
        assert key in message


@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        ({"sensor_width_mm": 13.2}, "missing sensor_height_mm"),
        ({"model": "no-such-camera"}, "sfap cameras"),
        ({"model": "dji-air-2s", "image_width_px": 5472.5}, "whole number"),
        ({"model": "dji-air-2s", "focal_length_mm": True}, "must be a number"),
        ({"model": "dji-air-2s", "focal_length_mm": "8.8"}, "must be a number"),
        ({"model": "dji-air-2s", "focal_length_mm": 700.0}, "not the 35 mm equivalent"),
        ({"model": "dji-air-2s", "shutter_s": float("nan")}, "finite"),
        ({"model": "dji-air-2s", "pixel_pitch_um": 3.3}, "pixel_pitch_um = 3.3"),
        ({"model": ""}, "non-empty string"),
    ],
)
def test_bad_camera_keys_name_the_value_and_the_place(data: dict[str, object], fragment: str) -> None:
    with pytest.raises(CameraError) as info:
        camera_from_mapping(data, where="spec.toml [camera]")
    assert fragment in str(info.value)
    assert "spec.toml [camera]" in str(info.value)


# --- the loader's own checks, on broken copies of a real entry -------------------------------


def test_a_real_entry_parses_alone() -> None:
    cameras = parse_cameras(_real_entry_text("dji-air-2s"))
    assert cameras == {"dji-air-2s": get_camera("dji-air-2s")}


@pytest.mark.parametrize(
    ("old", "new", "fragment"),
    [
        ('exif_make = "DJI"', 'exif_make = "DJI"\nlens = "8.38 mm"', "unknown key(s) lens"),
        ("sensor_height_mm = 8.8", "sensor_height_mm = 9.9", "pixel pitch is"),
        ("pixel_pitch_um = 2.4", "pixel_pitch_um = 2.0", "pixel_pitch_um = 2.0"),
        ('id = "dji-air-2s"', 'id = "DJI Air 2S"', "lowercase"),
        ("focal_length_mm = 8.38", "focal_length_mm = -8.38", "not a positive number"),
        ('source = "', '# source = "', "missing key(s) source"),
        ("image_width_px = 5472", "image_width_px = 5472.0", "whole number"),
    ],
)
def test_loader_rejects_broken_entries(old: str, new: str, fragment: str) -> None:
    text = _real_entry_text("dji-air-2s")
    assert old in text
    with pytest.raises(CameraError, match=re.escape(fragment)):
        parse_cameras(text.replace(old, new, 1))


def test_loader_rejects_duplicate_ids_and_bad_toml() -> None:
    text = _real_entry_text("dji-air-2s")
    with pytest.raises(CameraError, match="appears twice"):
        parse_cameras(text + "\n" + text)
    with pytest.raises(CameraError, match="not valid TOML"):
        parse_cameras(text + "\n[[camera]\n")
    with pytest.raises(CameraError, match="unknown top-level"):
        parse_cameras("version = 1\n" + text)


def test_every_field_of_every_entry_round_trips_through_the_mapping_api() -> None:
    # camera_from_mapping with all of a camera's own numbers rebuilds the same geometry.
    for camera in CAMERAS.values():
        rebuilt = camera_from_mapping(
            {
                "sensor_width_mm": camera.sensor_width_mm,
                "sensor_height_mm": camera.sensor_height_mm,
                "image_width_px": camera.image_width_px,
                "image_height_px": camera.image_height_px,
                "focal_length_mm": camera.focal_length_mm,
                "min_trigger_interval_s": camera.min_trigger_interval_s,
                "name": camera.name,
            },
            where="test",
        )
        assert math.isclose(rebuilt.gsd_cm(87.0), camera.gsd_cm(87.0), rel_tol=1e-12)
        landscape = Orientation.LANDSCAPE
        assert rebuilt.footprint(87.0, landscape) == camera.footprint(87.0, landscape)


# --- EXIF strings as cameras write them -----------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "model", "focal_mm", "size_px", "camera_id"),
    [
        ("DJI", "FC6310", 8.8, (5472, 3648), "dji-phantom-4-pro"),
        ("DJI", "FC330", 3.61, (4000, 3000), "dji-phantom-4"),
        ("DJI", "FC300X", 3.61, (4000, 3000), "dji-phantom-3-professional"),
        ("DJI", "FC220", 4.73, (4000, 3000), "dji-mavic-pro"),
        ("Hasselblad", "L1D-20c", 10.26, (5472, 3648), "dji-mavic-2-pro"),
        ("Hasselblad", "L2D-20c", 12.29, (5280, 3956), "dji-mavic-3"),
        ("Parrot", "Sequoia", 4.88, (4608, 3456), "parrot-sequoia-rgb"),
        ("Parrot", "Sequoia", 3.98, (1280, 960), "parrot-sequoia-multispectral"),
        ("Canon", "Canon PowerShot S110", 5.2, (4000, 3000), "canon-powershot-s110"),
        ("Canon", "Canon PowerShot ELPH 110 HS", 4.3, (4608, 3456), "canon-powershot-elph-110-hs"),
        ("SONY", "DSC-RX100M3", 8.8, (5472, 3648), "sony-rx100-iii"),
        ("SONY", "ILCE-7RM2", 35.0, (7952, 5304), "sony-a7r-ii-35mm"),
        ("MicaSense", "RedEdge-P", 5.5, (1456, 1088), "micasense-rededge-p-ms"),
        ("Skydio", "2+", 3.7, (4056, 3040), "skydio-2-plus"),
    ],
)
def test_exif_strings_as_cameras_write_them_find_their_camera(
    make: str, model: str, focal_mm: float, size_px: tuple[int, int], camera_id: str
) -> None:
    camera = match_exif(make, model, focal_mm, *size_px)
    assert camera is not None and camera.id == camera_id


def test_copr_kap_exif_read_by_exiv2_names_the_rebel_xsi_entry() -> None:
    # A real parser on a real frame: the entry's strings are the ones the camera wrote.
    from acquisition.exif import read_tags

    frame = sorted((SHARED_DATA / "copr_kap" / "images").iterdir())[0]
    tags = read_tags(frame)
    camera = CAMERAS["canon-eos-450d-30mm"]
    assert (tags.make, tags.model) == (camera.exif_make, camera.exif_model)
    assert tags.focal_length_mm == pytest.approx(camera.focal_length_mm)
    # The frames were halved: the same body, twice the pitch (planner's size check refuses them).
    assert match_exif(tags.make, tags.model, tags.focal_length_mm, tags.width_px, tags.height_px) is None
    assert match_exif(tags.make, tags.model, tags.focal_length_mm, None, None) is camera


@pytest.mark.parametrize("camera_id", CAMERA_IDS)
def test_names_shown_to_people_never_double_the_make(camera_id: str) -> None:
    from processing.image_tags import display_name

    camera = CAMERAS[camera_id]
    shown = display_name(camera.exif_make, camera.exif_model)
    words = shown.casefold().split()
    assert len(words) < 2 or words[0] != words[1], shown
    # The model string alone when it already starts with the make ("Canon PowerShot S110").
    if (camera.exif_model or "").casefold().startswith((camera.exif_make or "").casefold()):
        assert shown == camera.exif_model


def test_get_camera_parses_one_entry_giving_the_camera_the_whole_database_gives() -> None:
    """get_camera reads only the entry it is asked for (a small plan does not pay for parsing 80
    others): for every id, the same Camera as the whole database parsed and checked, and in a
    fresh process the whole database is not parsed for it."""
    import subprocess
    import sys

    from planner import camera_db

    whole = parse_cameras(camera_db._database_text())
    for camera_id, camera in whole.items():
        assert camera_db._entry_alone(camera_id) == camera, camera_id
    assert camera_db._entry_alone("no-such-camera") is None
    code = (
        "from planner import camera_db; camera = camera_db.get_camera('dji-mini-4-pro'); "
        "print(camera.id, camera_db._load_cameras.cache_info().currsize)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["dji-mini-4-pro", "0"]


def test_an_entry_that_cannot_be_read_alone_is_judged_by_the_whole_database(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A duplicated id (two blocks name it) is not taken from either block: the whole database is
    parsed and refuses it, as it refused it before."""
    from planner import camera_db

    text = camera_db._database_text()
    block = text[text.index('[[camera]]\nid = "dji-mini-4-pro"') :]
    block = block[: block.index("\n[[camera]]", 1) + 1]
    monkeypatch.setattr(camera_db, "_database_text", lambda: text + "\n" + block)
    camera_db._entry_alone.cache_clear()
    camera_db._load_cameras.cache_clear()
    try:
        with pytest.raises(CameraError, match="'dji-mini-4-pro' appears twice"):
            get_camera("dji-mini-4-pro")
    finally:
        camera_db._entry_alone.cache_clear()
        camera_db._load_cameras.cache_clear()
