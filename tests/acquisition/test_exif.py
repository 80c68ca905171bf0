"""acquisition.exif: capture times, GPS/XMP writing, read back by a second reader (exifread),
pixel data byte-identical, DJI XMP positions updated, and broken files named."""

from __future__ import annotations

import io
import shutil
from pathlib import Path

import exifread
import numpy as np
import pyexiv2
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from jpeg_edits import without_xmp_padding
from PIL import Image
from shared_data import SHARED_DATA

from acquisition import exif
from acquisition.errors import GeotagError

GARFIELD = SHARED_DATA / "garfield_rgb"
GARFIELD_FIRST = GARFIELD / "IMG_161122_163234_0000_RGB.JPG"


def make_jpeg(
    path: Path,
    *,
    date_time: str | None = "2024:05:17 10:11:12",
    sub_sec: str | None = "250",
    zone: str | None = None,
    xmp: dict[str, str] | None = None,
    progressive: bool = False,
    seed: int = 0,
) -> Path:
    """A small real JPEG (noise, so the entropy-coded data has 0xFF bytes) with a capture time."""
    rng = np.random.default_rng(seed)
    pixels = rng.integers(0, 256, size=(48, 64, 3), dtype=np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="JPEG", quality=90, progressive=progressive)
    image = pyexiv2.ImageData(buffer.getvalue())
    tags = {"Exif.Image.Make": "TestCam", "Exif.Image.Model": "T1"}
    if date_time is not None:
        tags["Exif.Photo.DateTimeOriginal"] = date_time
    if sub_sec is not None:
        tags["Exif.Photo.SubSecTimeOriginal"] = sub_sec
    if zone is not None:
        tags["Exif.Photo.OffsetTimeOriginal"] = zone
    image.modify_exif(tags)
    if xmp:
        exif._register_namespaces()
        image.modify_xmp(xmp)
    path.write_bytes(image.get_bytes())
    image.close()
    return path


def _exifread(path: Path) -> dict[str, object]:
    with path.open("rb") as handle:
        return dict(exifread.process_file(handle, details=False))


def _dms(tag: object) -> float:
    values = [float(v.num) / float(v.den) for v in tag.values]  # type: ignore[attr-defined]
    return values[0] + values[1] / 60 + values[2] / 3600


# ---------------------------------------------------------------------------- capture time


def test_capture_time_with_subseconds_and_zone(tmp_path: Path) -> None:
    path = make_jpeg(tmp_path / "a.jpg", date_time="2024:05:17 10:11:12", sub_sec="25", zone="+02:00")
    tags = exif.read_tags(path)
    # 10:11:12.25 at UTC+2 is 08:11:12.25 UTC; "25" is 25 hundredths (EXIF sub-second digits).
    assert tags.capture_time_s == pytest.approx(1715933472.25, abs=1e-6)
    assert tags.capture_time_zone_known
    assert tags.make == "TestCam" and tags.width_px == 64 and tags.height_px == 48


def test_capture_time_without_zone_is_the_wall_clock(tmp_path: Path) -> None:
    tags = exif.read_tags(make_jpeg(tmp_path / "a.jpg", sub_sec="5"))
    assert tags.capture_time_s == pytest.approx(1715940672.5)
    assert not tags.capture_time_zone_known


def test_parse_capture_time_forms() -> None:
    assert exif.parse_capture_time("2024-05-17T10:11:12.125-05:00") == (1715958672.125, True)
    assert exif.parse_capture_time("0000:00:00 00:00:00") is None
    assert exif.parse_capture_time("2024:02:30 10:00:00") is None  # no 30 February
    assert exif.parse_capture_time("garbage") is None


def test_no_capture_time(tmp_path: Path) -> None:
    tags = exif.read_tags(make_jpeg(tmp_path / "a.jpg", date_time=None, sub_sec=None))
    assert tags.capture_time_s is None


def test_garfield_tags_agree_with_exifread() -> None:
    tags = exif.read_tags(GARFIELD_FIRST)
    other = _exifread(GARFIELD_FIRST)
    assert tags.gps_lat_deg == pytest.approx(_dms(other["GPS GPSLatitude"]), abs=1e-12)
    assert tags.gps_lon_deg == pytest.approx(-_dms(other["GPS GPSLongitude"]), abs=1e-12)
    alt = other["GPS GPSAltitude"].values[0]  # type: ignore[attr-defined]
    assert tags.gps_alt_amsl_m == pytest.approx(alt.num / alt.den)
    assert tags.capture_time_text == str(other["EXIF DateTimeOriginal"])
    assert (tags.make, tags.model, tags.width_px, tags.height_px) == (
        "Parrot",
        "Sequoia",
        4608,
        3456,
    )
    assert tags.camera_yaw_deg == pytest.approx(-16.7996)
    assert tags.xy_accuracy_m == pytest.approx(2.301)
    # 2016-11-22 16:32:34.498032 camera clock; GPS time stamp 16:32:33.853.
    assert tags.capture_time_s == pytest.approx(1479832354.498032)
    assert tags.gps_time_utc_s == pytest.approx(1479832353.853)


# ---------------------------------------------------------------------------- compressed data


def test_compressed_image_data_is_sos_to_eoi(tmp_path: Path) -> None:
    data = make_jpeg(tmp_path / "a.jpg").read_bytes()
    scan = exif.compressed_image_data(data)
    assert scan.startswith(b"\xff\xda") and scan.endswith(b"\xff\xd9")
    assert data.index(b"\xff\xda") == data.index(scan)
    # Bytes appended after EOI (preview images on DJI files) are not image data.
    assert exif.compressed_image_data(data + b"\xff\xd8trailer\xff\xd9") == scan


def test_compressed_image_data_progressive_covers_all_scans(tmp_path: Path) -> None:
    data = make_jpeg(tmp_path / "p.jpg", progressive=True).read_bytes()
    scan = exif.compressed_image_data(data)
    assert scan.count(b"\xff\xda") > 1 and data.endswith(scan)


def test_compressed_image_data_refuses_broken_files(tmp_path: Path) -> None:
    data = make_jpeg(tmp_path / "a.jpg").read_bytes()
    with pytest.raises(GeotagError, match="no EOI"):
        exif.compressed_image_data(data[:-200])
    with pytest.raises(GeotagError, match="not a JPEG"):
        exif.compressed_image_data(b"GIF89a")


# ---------------------------------------------------------------------------- writing


def _tag(**changes: float | None) -> exif.GeoTag:
    values: dict[str, float | None] = {
        "lat_deg": -33.8567844,
        "lon_deg": -151.2152967,
        "alt_amsl_m": -12.345,
        "time_utc_s": 1715933472.25,
        "yaw_deg": 271.5,
        "pitch_deg": 2.25,
        "roll_deg": -1.5,
        "xy_accuracy_m": 0.8,
        "z_accuracy_m": 1.6,
    }
    values.update(changes)
    return exif.GeoTag(**values)  # type: ignore[arg-type]


def test_written_tags_read_back_by_exifread_and_pixels_identical(tmp_path: Path) -> None:
    src = make_jpeg(tmp_path / "src.jpg")
    dst = tmp_path / "out" / "dst.jpg"
    tag = _tag()
    exif.write_geotag(src, dst, tag)
    other = _exifread(dst)
    assert str(other["GPS GPSLatitudeRef"]) == "S" and str(other["GPS GPSLongitudeRef"]) == "W"
    # Seconds are written to 1e-5 s: 0.3 mm on the ground.
    assert -_dms(other["GPS GPSLatitude"]) == pytest.approx(tag.lat_deg, abs=1e-5 / 3600)
    assert -_dms(other["GPS GPSLongitude"]) == pytest.approx(tag.lon_deg, abs=1e-5 / 3600)
    assert other["GPS GPSAltitudeRef"].values == [1]  # type: ignore[attr-defined]
    alt = other["GPS GPSAltitude"].values[0]  # type: ignore[attr-defined]
    assert alt.num / alt.den == pytest.approx(12.345)
    assert str(other["GPS GPSDate"]) == "2024:05:17"
    hms = [v.num / v.den for v in other["GPS GPSTimeStamp"].values]  # type: ignore[attr-defined]
    assert hms == pytest.approx([8, 11, 12.25])
    direction = other["GPS GPSImgDirection"].values[0]  # type: ignore[attr-defined]
    assert direction.num / direction.den == pytest.approx(271.5)
    assert str(other["GPS GPSImgDirectionRef"]) == "T"
    assert str(other["GPS GPSMapDatum"]) == "WGS-84"
    # XMP in the Pix4D namespace.
    raw = dst.read_bytes()
    assert b"http://pix4d.com/camera/1.0/" in raw
    back = exif.read_tags(dst)
    assert (back.camera_yaw_deg, back.camera_pitch_deg, back.camera_roll_deg) == (271.5, 2.25, -1.5)
    assert (back.xy_accuracy_m, back.z_accuracy_m) == (0.8, 1.6)
    assert back.gps_alt_amsl_m == pytest.approx(-12.345)
    # Pixel data: the compressed bytes and the decoded pixels are identical.
    assert exif.compressed_image_data(dst) == exif.compressed_image_data(src)
    assert np.array_equal(np.asarray(Image.open(dst)), np.asarray(Image.open(src)))
    # The source was not touched, and no XMP DJI tags were invented.
    assert exif.read_tags(src).gps_lat_deg is None
    assert b"drone-dji" not in raw


@settings(max_examples=60, deadline=None)
@given(
    lat=st.floats(-89.999, 89.999),
    lon=st.floats(-179.999, 179.999),
    alt=st.floats(-400.0, 9000.0),
)
def test_position_round_trip_property(
    tmp_path_factory: pytest.TempPathFactory, lat: float, lon: float, alt: float
) -> None:
    folder = tmp_path_factory.mktemp("rt")
    src = make_jpeg(folder / "a.jpg")
    data = exif.geotag_bytes(src.read_bytes(), exif.GeoTag(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt))
    (folder / "b.jpg").write_bytes(data)
    back = exif.read_tags(folder / "b.jpg")
    assert back.gps_lat_deg == pytest.approx(lat, abs=0.51e-5 / 3600)
    assert back.gps_lon_deg == pytest.approx(lon, abs=0.51e-5 / 3600)
    assert back.gps_alt_amsl_m == pytest.approx(alt, abs=0.0005)


def test_dji_xmp_positions_are_updated(tmp_path: Path) -> None:
    xmp = {
        "Xmp.drone-dji.GpsLatitude": "+47.000000",
        "Xmp.drone-dji.GpsLongtitude": "+8.000000",  # the misspelling of older DJI firmware
        "Xmp.drone-dji.AbsoluteAltitude": "+500.00",
        "Xmp.drone-dji.RelativeAltitude": "+80.00",
        "Xmp.drone-dji.GimbalPitchDegree": "-90.0",
    }
    src = make_jpeg(tmp_path / "dji.jpg", xmp=xmp)
    before = exif.read_tags(src)
    assert before.has_dji_position and before.dji_lon_deg == 8.0
    exif.write_geotag(src, tmp_path / "out.jpg", _tag(alt_amsl_m=412.5, alt_rel_home_m=75.25))
    after = exif.read_tags(tmp_path / "out.jpg")
    assert after.dji_lat_deg == pytest.approx(-33.8567844)
    assert after.dji_lon_deg == pytest.approx(-151.2152967)
    assert after.dji_alt_amsl_m == pytest.approx(412.5)
    assert after.dji_alt_rel_home_m == pytest.approx(75.25)
    raw = pyexiv2.Image(str(tmp_path / "out.jpg"))
    try:
        kept = raw.read_xmp()
    finally:
        raw.close()
    assert kept["Xmp.drone-dji.GimbalPitchDegree"] == "-90.0"  # what we do not know stays
    assert "Xmp.drone-dji.GpsLongitude" not in kept  # no second longitude spelling invented


def test_dji_relative_altitude_removed_when_unknown(tmp_path: Path) -> None:
    xmp = {"Xmp.drone-dji.GpsLatitude": "+47.0", "Xmp.drone-dji.RelativeAltitude": "+80.00"}
    src = make_jpeg(tmp_path / "dji.jpg", xmp=xmp)
    exif.write_geotag(src, tmp_path / "out.jpg", _tag())
    assert exif.read_tags(tmp_path / "out.jpg").dji_alt_rel_home_m is None


def test_write_in_place_and_refuse_overwrite(tmp_path: Path) -> None:
    src = make_jpeg(tmp_path / "a.jpg")
    scan = exif.compressed_image_data(src)
    exif.write_geotag(src, src, _tag())
    assert exif.read_tags(src).gps_lat_deg == pytest.approx(-33.8567844)
    assert exif.compressed_image_data(src) == scan
    other = make_jpeg(tmp_path / "b.jpg")
    from planner.errors import OutputExistsError

    with pytest.raises(OutputExistsError, match="--overwrite"):
        exif.write_geotag(other, src, _tag())


def test_strip_gps_on_garfield(tmp_path: Path) -> None:
    copy = tmp_path / GARFIELD_FIRST.name
    shutil.copy(GARFIELD_FIRST, copy)
    exif.strip_gps(copy, tmp_path / "s.jpg", attitude=True)
    stripped = exif.read_tags(tmp_path / "s.jpg")
    assert (
        stripped.gps_lat_deg is None and stripped.gps_alt_amsl_m is None and stripped.gps_time_utc_s is None
    )
    assert stripped.camera_yaw_deg is None and stripped.xy_accuracy_m is None
    assert stripped.capture_time_s == exif.read_tags(copy).capture_time_s
    assert not any(k.startswith("GPS ") and k != "GPS GPSInfo" for k in _exifread(tmp_path / "s.jpg"))
    assert exif.compressed_image_data(tmp_path / "s.jpg") == exif.compressed_image_data(GARFIELD_FIRST)


def test_geotag_values_are_validated() -> None:
    with pytest.raises(GeotagError, match="latitude 91"):
        exif.GeoTag(lat_deg=91.0, lon_deg=0.0)
    with pytest.raises(GeotagError, match="alt_amsl_m is nan"):
        exif.GeoTag(lat_deg=0.0, lon_deg=0.0, alt_amsl_m=float("nan"))
    with pytest.raises(GeotagError, match="accuracies"):
        exif.GeoTag(lat_deg=0.0, lon_deg=0.0, xy_accuracy_m=-1.0)


def test_unreadable_files_are_named(tmp_path: Path) -> None:
    empty = tmp_path / "empty.jpg"
    empty.write_bytes(b"")
    with pytest.raises(GeotagError, match=r"empty\.jpg: not a JPEG"):
        exif.read_tags(empty)
    text = tmp_path / "notes.jpg"
    text.write_text("not an image")
    with pytest.raises(GeotagError, match=r"notes\.jpg"):
        exif.read_tags(text)
    truncated = tmp_path / "cut.jpg"
    truncated.write_bytes(make_jpeg(tmp_path / "whole.jpg").read_bytes()[:300])
    with pytest.raises(GeotagError, match=r"cut\.jpg"):
        exif.write_geotag(truncated, tmp_path / "x.jpg", _tag())


def test_stale_gps_and_attitude_of_the_old_fix_are_removed(tmp_path: Path) -> None:
    copy = tmp_path / GARFIELD_FIRST.name
    shutil.copy(GARFIELD_FIRST, copy)
    exif.write_geotag(copy, tmp_path / "out.jpg", exif.GeoTag(lat_deg=1.5, lon_deg=-2.25))
    other = _exifread(tmp_path / "out.jpg")
    gps = {k for k in other if k.startswith("GPS ")}
    assert gps == {
        "GPS GPSVersionID",
        "GPS GPSLatitudeRef",
        "GPS GPSLatitude",
        "GPS GPSLongitudeRef",
        "GPS GPSLongitude",
        "GPS GPSMapDatum",
    }  # no old speed, status, altitude or time
    back = exif.read_tags(tmp_path / "out.jpg")
    assert (back.gps_lat_deg, back.gps_lon_deg) == (1.5, -2.25)
    assert back.camera_yaw_deg is None and back.xy_accuracy_m is None  # no attitude of another pose
    assert back.capture_time_s == exif.read_tags(copy).capture_time_s


def test_xmp_exif_gps_copies_are_updated(tmp_path: Path) -> None:
    xmp = {"Xmp.exif.GPSLatitude": "10,0.0N", "Xmp.exif.GPSLongitude": "20,0.0E"}
    src = make_jpeg(tmp_path / "x.jpg", xmp=xmp)
    exif.write_geotag(src, tmp_path / "out.jpg", _tag())
    image = pyexiv2.Image(str(tmp_path / "out.jpg"))
    try:
        written = image.read_xmp()
    finally:
        image.close()
    lat = written["Xmp.exif.GPSLatitude"]
    assert lat.endswith("S") and lat.startswith("33,")
    assert float(lat[3:-1]) / 60 + 33 == pytest.approx(33.8567844, abs=1e-9)
    assert written["Xmp.exif.GPSLongitude"].startswith("151,") and written["Xmp.exif.GPSLongitude"].endswith(
        "W"
    )
    assert "Xmp.exif.GPSAltitude" not in written  # not carried before: not invented


# ---------------------------------------------------------------------------- header-only writing

COPR = SHARED_DATA / "copr_kap" / "images"


def _exiv2_on_whole_file(data: bytes, tag: exif.GeoTag) -> bytes:
    """The independent construction: exiv2 given the whole file (image data and all), the way
    tags were written before the header-only path existed."""
    exif._register_namespaces()
    image = pyexiv2.ImageData(data)
    try:
        exif_map, xmp_map = image.read_exif(), image.read_xmp()
        values = exif._exif_gps_values(tag)
        for key in exif_map:
            if key.startswith("Exif.GPSInfo.") and key not in values:
                values[key] = None
        image.modify_exif({k: v for k, v in values.items() if v is not None or k in exif_map})
        xmp_values = exif._xmp_values(tag, xmp_map)
        if xmp_values:
            image.modify_xmp(xmp_values)
        out: bytes = image.get_bytes()
    finally:
        image.close()
    return out


def _exiftool_all(paths: list[Path]) -> list[dict[str, object]]:
    """Every tag exiftool reads (all groups, binary values such as thumbnails and maker-note
    blocks as base64), minus the file system's and the layout's own (offsets, the XMP toolkit
    name exiv2 stamps on a packet it creates)."""
    import json
    import subprocess

    exiftool = shutil.which("exiftool")
    assert exiftool is not None, "exiftool is needed (Debian: libimage-exiftool-perl)"
    done = subprocess.run(
        [exiftool, "-j", "-a", "-G1", "-n", "-u", "-b", *map(str, paths)],
        capture_output=True,
        text=True,
        check=True,
    )
    skip_groups = ("System:", "File:", "ExifTool:", "Composite:")
    return [
        {
            k: v
            for k, v in record.items()
            if not k.startswith(skip_groups)
            and k not in ("SourceFile", "XMP-x:XMPToolkit")
            and not k.endswith(("Offset", "Offsets"))
        }
        for record in json.loads(done.stdout)
    ]


def _validate(path: Path) -> str:
    import subprocess

    done = subprocess.run(
        ["exiftool", "-validate", "-warning", "-a", "-G1", str(path)], capture_output=True, text=True
    )
    return done.stdout.replace(str(path), "FILE")


FAST_TAGS = [_tag(alt_rel_home_m=80.0), exif.GeoTag(lat_deg=41.4, lon_deg=-81.6, xy_accuracy_m=1.5)]


@pytest.mark.parametrize("tag", FAST_TAGS, ids=["full", "position-only"])
def test_fast_write_reads_as_exiv2s_write_in_exiftool(tmp_path: Path, tag: exif.GeoTag) -> None:
    """Every real frame (Sequoia: EXIF GPS and Pix4D XMP; Canon: maker notes, thumbnail, no XMP)
    written by the Python path reads, in exiftool, tag for tag as exiv2's write of the whole file;
    exiftool's validation finds the same; the image data is the source's."""
    sources = sorted(GARFIELD.glob("*.JPG")) + sorted(COPR.glob("*.jpg"))
    fast, slow = [], []
    for k, source in enumerate(sources):
        fast.append(exif.write_geotag(source, tmp_path / f"fast_{k}.jpg", tag))
        slow.append(tmp_path / f"exiv2_{k}.jpg")
        slow[-1].write_bytes(_exiv2_on_whole_file(source.read_bytes(), tag))
        assert fast[-1].read_bytes() != slow[-1].read_bytes()  # the Python path wrote it, not exiv2
        assert exif.compressed_image_data(fast[-1]) == exif.compressed_image_data(source)
    read_fast, read_slow = _exiftool_all(fast), _exiftool_all(slow)
    for source, a, b in zip(sources, read_fast, read_slow, strict=True):
        assert a == b, source.name
    assert any("MakerNotes:" in k or k.startswith("Canon") for k in read_fast[-1])
    for k in (0, len(sources) - 1):
        assert _validate(fast[k]) == _validate(slow[k])
    # The old fix is zeroed, not left behind unreferenced: one position per file.
    import struct

    for source, out in zip(sources, fast, strict=True):
        old = exif.read_tags(source)
        if old.gps_lat_deg is None:
            continue
        data = source.read_bytes()
        order = (
            ">" if data[data.index(b"Exif\x00\x00") + 6 : data.index(b"Exif\x00\x00") + 8] == b"MM" else "<"
        )
        image = pyexiv2.Image(str(source))
        try:
            text = image.read_exif()["Exif.GPSInfo.GPSLatitude"]
        finally:
            image.close()
        numbers = [int(v) for part in text.split() for v in part.split("/")]
        raw = struct.pack(f"{order}{len(numbers)}I", *numbers)
        assert raw in data and raw not in out.read_bytes(), source.name


def test_header_only_exiv2_write_equals_exiv2_on_the_whole_file() -> None:
    """The exiv2 path (files the Python path does not handle) on the header alone gives the bytes
    exiv2 gives on the whole file."""
    for source in (GARFIELD_FIRST, sorted(COPR.glob("*.jpg"))[0]):
        tag = _tag(alt_rel_home_m=80.0)
        assert exif.geotag_bytes(source.read_bytes(), tag) == _exiv2_on_whole_file(source.read_bytes(), tag)


def test_files_the_fast_path_does_not_handle_go_to_exiv2(tmp_path: Path) -> None:
    """No EXIF segment at all, and XMP properties in a structure: written by exiv2, byte for byte."""
    plain = tmp_path / "plain.jpg"
    Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(plain, format="JPEG")
    structured = make_jpeg(tmp_path / "seq.jpg")
    data = structured.read_bytes()
    packet = (
        b'<?xpacket begin="" id="W5M0MpCehiHzreSzNTczkc9d"?><x:xmpmeta xmlns:x="adobe:ns:meta/">'
        b'<rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description rdf:about="" '
        b'xmlns:Camera="http://pix4d.com/camera/1.0/"><Camera:Yaw><rdf:Seq><rdf:li>1</rdf:li></rdf:Seq>'
        b'</Camera:Yaw></rdf:Description></rdf:RDF></x:xmpmeta><?xpacket end="w"?>'
    )
    payload = b"http://ns.adobe.com/xap/1.0/\x00" + packet
    segment = b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload
    structured.write_bytes(data[:2] + segment + data[2:])
    for source in (plain, structured):
        out = exif.write_geotag(source, tmp_path / f"out_{source.name}", _tag())
        assert out.read_bytes() == _exiv2_on_whole_file(source.read_bytes(), _tag())


def test_xmp_element_form_and_new_namespace(tmp_path: Path) -> None:
    """DJI-style XMP with properties as elements, no Pix4D namespace yet: the elements are
    replaced, the namespace declared, and exiftool reads it as it reads exiv2's write."""
    base = make_jpeg(tmp_path / "dji.jpg").read_bytes()
    packet = (
        '<?xpacket begin="\ufeff" id="W5M0MpCehiHzreSzNTczkc9d"?>\n<x:xmpmeta xmlns:x="adobe:ns:meta/">\n'
        ' <rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">\n'
        '  <rdf:Description rdf:about="DJI Meta Data" xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/">\n'
        "   <drone-dji:GpsLatitude>+10.000000</drone-dji:GpsLatitude>\n"
        "   <drone-dji:GpsLongtitude>+20.000000</drone-dji:GpsLongtitude>\n"
        "   <drone-dji:AbsoluteAltitude>+100.00</drone-dji:AbsoluteAltitude>\n"
        "   <drone-dji:RelativeAltitude>+30.00</drone-dji:RelativeAltitude>\n"
        "   <drone-dji:GimbalPitchDegree>-90.00</drone-dji:GimbalPitchDegree>\n"
        "  </rdf:Description>\n </rdf:RDF>\n</x:xmpmeta>\n" + " " * 200 + '\n<?xpacket end="w"?>'
    ).encode()
    payload = b"http://ns.adobe.com/xap/1.0/\x00" + packet
    src = tmp_path / "dji_xmp.jpg"
    src.write_bytes(base[:2] + b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload + base[2:])
    tag = _tag(alt_rel_home_m=80.0)
    fast = exif.write_geotag(src, tmp_path / "fast.jpg", tag)
    slow = tmp_path / "exiv2.jpg"
    slow.write_bytes(_exiv2_on_whole_file(src.read_bytes(), tag))
    assert fast.read_bytes() != slow.read_bytes()
    read_fast, read_slow = _exiftool_all([fast, slow])
    # exiv2 rewrites the packet and drops the description's rdf:about; the text edit keeps it.
    assert read_fast.pop("XMP-rdf:About") == "DJI Meta Data" and "XMP-rdf:About" not in read_slow
    assert read_fast == read_slow
    assert read_fast["XMP-drone-dji:GPSLatitude"] == pytest.approx(-33.8567844)
    assert read_fast["XMP-drone-dji:GPSLongtitude"] == pytest.approx(-151.2152967)
    assert read_fast["XMP-drone-dji:RelativeAltitude"] == "+80.000"
    assert read_fast["XMP-drone-dji:GimbalPitchDegree"] == -90.0
    assert read_fast["XMP-Camera:Yaw"] == 271.5


def test_fast_reader_agrees_with_exiv2_on_real_frames() -> None:
    """read_tags and the camera tags from the Python reader equal exiv2's (pyexiv2's maps) on
    every real frame."""
    for source in sorted(GARFIELD.glob("*.JPG")) + sorted(COPR.glob("*.jpg")):
        image = pyexiv2.Image(str(source))
        try:
            exif_map, xmp_map = image.read_exif(), image.read_xmp()
            width, height = image.get_pixel_width(), image.get_pixel_height()
        finally:
            image.close()
        tags, camera = exif.read_tags_and_camera(source)
        assert tags == exif.tags_from_maps(str(source), exif_map, xmp_map, width_px=width, height_px=height)
        assert camera == exif.camera_tags_from_maps(exif_map, xmp_map)
        assert tags.capture_time_s is not None


def test_bytes_after_the_header_are_the_source_bytes(tmp_path: Path) -> None:
    """Image data, EOI and a trailer after EOI (DJI preview images) are copied as they are."""
    data = make_jpeg(tmp_path / "p.jpg", progressive=True, xmp={"Xmp.drone-dji.GpsLatitude": "+1.0"})
    trailer = b"\xff\xd8" + bytes(range(256)) * 40 + b"\xff\xd9"
    src = tmp_path / "trailer.jpg"
    src.write_bytes(data.read_bytes() + trailer)
    exif.write_geotag(src, tmp_path / "out.jpg", _tag())
    out = (tmp_path / "out.jpg").read_bytes()
    raw = src.read_bytes()
    tail = raw[raw.index(b"\xff\xda") :]  # no SOS marker in this small file's header
    assert out.endswith(tail) and out.endswith(trailer)
    assert exif.read_tags(tmp_path / "out.jpg").dji_lat_deg == pytest.approx(-33.8567844)


def _read_with_exiftool(path: Path) -> dict[str, object]:
    import json
    import subprocess

    exiftool = shutil.which("exiftool")
    assert exiftool is not None, "exiftool is needed (Debian: libimage-exiftool-perl)"
    done = subprocess.run(
        [exiftool, "-j", "-n", "-G1", "-a", "-GPS:all", "-XMP-Camera:all", "-MakerNotes:all", str(path)],
        capture_output=True,
        text=True,
        check=True,
    )
    record: dict[str, object] = json.loads(done.stdout)[0]
    record.pop("SourceFile")
    return record


def test_exiftool_reads_the_tags_and_the_maker_notes_survive(tmp_path: Path) -> None:
    source = sorted(COPR.glob("*.jpg"))[0]
    tag = _tag()
    exif.write_geotag(source, tmp_path / "out.jpg", tag)
    before, after = _read_with_exiftool(source), _read_with_exiftool(tmp_path / "out.jpg")
    notes_before = {k: v for k, v in before.items() if k.startswith("Canon")}
    assert len(notes_before) > 50  # the Canon maker notes exiftool decodes
    assert {k: v for k, v in after.items() if k.startswith("Canon")} == notes_before
    # The GPS group holds unsigned values and their hemisphere references.
    assert (after["GPS:GPSLatitudeRef"], after["GPS:GPSLongitudeRef"]) == ("S", "W")
    assert after["GPS:GPSLatitude"] == pytest.approx(-tag.lat_deg, abs=1e-8)
    assert after["GPS:GPSLongitude"] == pytest.approx(-tag.lon_deg, abs=1e-8)
    assert after["GPS:GPSAltitude"] == pytest.approx(12.345) and after["GPS:GPSAltitudeRef"] == 1
    assert after["GPS:GPSImgDirection"] == pytest.approx(271.5)
    assert (after["XMP-Camera:Yaw"], after["XMP-Camera:Pitch"], after["XMP-Camera:Roll"]) == (
        271.5,
        2.25,
        -1.5,
    )
    assert exif.compressed_image_data(tmp_path / "out.jpg") == exif.compressed_image_data(source)


def _damaged_copies(folder: Path) -> dict[str, Path]:
    """Real frames with their end marker cut off or overwritten, as cards hold them."""
    data = GARFIELD_FIRST.read_bytes()
    assert data.endswith(b"\xff\xd9")
    cases = {
        "cut.jpg": data[:-5000],  # the camera stopped writing mid-scan
        "zeroed.jpg": data[:-2] + b"\x00\x00",  # the end marker overwritten
        "no_eoi.jpg": data[:-2],
    }
    paths = {}
    for name, content in cases.items():
        paths[name] = folder / name
        paths[name].write_bytes(content)
    return paths


def test_missing_end_marker_is_tagged_with_a_warning_naming_the_file(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from PIL import ImageFile

    for name, src in _damaged_copies(tmp_path).items():
        caplog.clear()
        dst = tmp_path / "out" / name
        with caplog.at_level("WARNING", logger="acquisition.exif"):
            exif.write_geotag(src, dst, _tag())
        assert [r.getMessage() for r in caplog.records if name in r.getMessage() and "EOI" in r.getMessage()]
        other = _exifread(dst)
        assert -_dms(other["GPS GPSLatitude"]) == pytest.approx(-33.8567844, abs=1e-5 / 3600)
        raw, out = src.read_bytes(), dst.read_bytes()
        header_in = exif._split_bytes(raw, name).sos_offset
        header_out = exif._split_bytes(out, name).sos_offset
        assert out[header_out:] == raw[header_in:]  # every byte of the damaged scan, unchanged
        previous = ImageFile.LOAD_TRUNCATED_IMAGES
        ImageFile.LOAD_TRUNCATED_IMAGES = True
        try:  # a decoder still reads it, to the same pixels as the source
            assert np.array_equal(np.asarray(Image.open(dst)), np.asarray(Image.open(src)))
        finally:
            ImageFile.LOAD_TRUNCATED_IMAGES = previous


def test_whole_files_and_trailers_raise_no_end_marker_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    src = tmp_path / "trailer.jpg"
    src.write_bytes(GARFIELD_FIRST.read_bytes() + b"\x00" * 64)  # padding after EOI
    with caplog.at_level("WARNING", logger="acquisition.exif"):
        exif.write_geotag(GARFIELD_FIRST, tmp_path / "a.jpg", _tag())
        exif.write_geotag(src, tmp_path / "b.jpg", _tag())
    assert not [r for r in caplog.records if "EOI" in r.getMessage()]


def test_write_geotags_batch(tmp_path: Path) -> None:
    damaged = _damaged_copies(tmp_path)
    broken = tmp_path / "broken.jpg"
    broken.write_bytes(GARFIELD_FIRST.read_bytes()[:300])  # cut inside the EXIF segment
    sources = [*sorted(GARFIELD.glob("*.JPG"))[:5], damaged["cut.jpg"], broken]
    tags = [_tag(lat_deg=10.0 + k) for k in range(len(sources))]
    for workers in (1, 3):
        out = tmp_path / f"w{workers}"
        out.mkdir()
        jobs = [
            exif.GeotagJob(src=str(s), dst=str(out / s.name), tag=t)
            for s, t in zip(sources, tags, strict=True)
        ]
        done: list[int] = []
        results = exif.write_geotags(jobs, workers=workers, atomic=False, progress=done.append)
        assert done[-1] == len(jobs)
        assert [r.src for r in results] == [str(s) for s in sources]
        assert [r.written for r in results] == [True] * 6 + [False]
        assert results[-1].error is not None and "broken.jpg" in results[-1].error
        assert not (out / "broken.jpg").exists()
        assert [bool(r.warnings) for r in results[:6]] == [False] * 5 + [True]
        assert "cut.jpg" in results[5].warnings[0]
        for k, source in enumerate(sources[:6]):
            assert exif.read_tags(out / source.name).gps_lat_deg == pytest.approx(10.0 + k)
    for source in sources[:6]:
        assert (tmp_path / "w1" / source.name).read_bytes() == (tmp_path / "w3" / source.name).read_bytes()


# ---------------------------------------------------------------------------- one read per frame


def test_a_frame_read_once_is_written_from_what_was_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Geotag reads every header for its capture time, then writes: the write uses that read
    (the header bytes re-read in one call, its maps not parsed again) and gives the same bytes
    as a write that reads the header afresh; only the read-back parses the new header (its XMP
    packet parsed once a frame, against twice without the read)."""
    from acquisition import jpeg_meta

    sources = sorted(GARFIELD.glob("*.JPG"))
    parses: list[int] = []
    real_parse = jpeg_meta._parsed_xmp_map

    def counting(data: bytes):  # type: ignore[no-untyped-def]
        parses.append(1)
        return real_parse(data)

    for use_seen in (False, True):
        out = tmp_path / str(use_seen)
        out.mkdir()
        jobs = []
        for k, source in enumerate(sources):
            tags, seen = exif.read_tags_and_header(source)
            assert seen is not None and tags.capture_time_s is not None
            jobs.append(
                exif.GeotagJob(
                    src=str(source),
                    dst=str(out / source.name),
                    tag=_tag(lat_deg=10.0 + k),
                    seen=seen if use_seen else None,
                )
            )
        parses.clear()
        monkeypatch.setattr(jpeg_meta, "_parsed_xmp_map", counting)
        results = exif.write_geotags(jobs, workers=1, atomic=False)
        monkeypatch.setattr(jpeg_meta, "_parsed_xmp_map", real_parse)
        assert all(r.written for r in results)
        # without the read: the header parsed before the patch and after; with it: after only
        assert len(parses) == (1 if use_seen else 2) * len(sources)
    for source in sources:
        assert (tmp_path / "True" / source.name).read_bytes() == (
            tmp_path / "False" / source.name
        ).read_bytes()


def test_a_frame_changed_since_it_was_read_is_read_again(tmp_path: Path) -> None:
    """The read is used only while the file is the one read: rewritten since (same size, same
    layout, another capture time), the new header is read and written; with the same identity
    but a stale map the read-back catches the difference and exiv2 writes it. Either way the
    tags are right."""
    second = sorted(GARFIELD.glob("*.JPG"))[1]
    card = tmp_path / "frame.jpg"
    shutil.copyfile(second, card)
    _, seen = exif.read_tags_and_header(card)
    assert seen is not None
    data = card.read_bytes()
    edited = data.replace(b"2016:11:22 16:32:", b"2016:11:22 17:45:")  # same length, same layout
    assert edited != data and len(edited) == len(data)
    with card.open("r+b") as handle:  # the crew fixed the camera clock between the two passes
        handle.write(edited)
    exif.write_geotags(
        [exif.GeotagJob(src=str(card), dst=str(tmp_path / "a.jpg"), tag=_tag(lat_deg=12.5), seen=seen)],
        atomic=False,
    )
    fresh = tmp_path / "fresh.jpg"
    fresh.write_bytes(edited)
    exif.write_geotag(fresh, tmp_path / "b.jpg", _tag(lat_deg=12.5))
    assert (tmp_path / "a.jpg").read_bytes() == (tmp_path / "b.jpg").read_bytes()

    # Same file, same identity, but the map the read kept says another capture time.
    _, seen = exif.read_tags_and_header(second)
    assert seen is not None
    stale = exif.HeaderSnapshot(
        identity=seen.identity,
        sos_offset=seen.sos_offset,
        sos_segment=seen.sos_segment,
        exif={**seen.exif, "Exif.Photo.DateTimeOriginal": "2001:01:01 00:00:00"},
        xmp=seen.xmp,
    )
    result = exif.write_geotags(
        [exif.GeotagJob(src=str(second), dst=str(tmp_path / "c.jpg"), tag=_tag(lat_deg=12.5), seen=stale)],
        atomic=False,
    )
    assert result[0].written
    back, original = exif.read_tags(tmp_path / "c.jpg"), exif.read_tags(second)
    assert back.gps_lat_deg == pytest.approx(12.5)
    assert back.capture_time_s == original.capture_time_s
    assert exif.compressed_image_data(tmp_path / "c.jpg") == exif.compressed_image_data(second)


# ---------------------------------------------------------------------------- image data in place


def _xmp_padding(header: bytes) -> int:
    """Bytes of whitespace before the XMP packet's end processing instruction."""
    end = header.rfind(b"<?xpacket end=")
    start = end
    while header[start - 1 : start] in (b" ", b"\n", b"\r", b"\t"):
        start -= 1
    return end - start


def test_the_xmp_padding_keeps_the_image_data_where_it_was(tmp_path: Path) -> None:
    """A frame with XMP padding (every Sequoia frame has 2 KiB of it) keeps its header length:
    the growth of the tags comes out of the padding and the image data stays at its offset.
    The new tags read back."""
    for source in sorted(GARFIELD.glob("*.JPG"))[:6]:
        out = tmp_path / source.name
        exif.write_geotag(source, out, _tag(lat_deg=47.25))
        data_in, data_out = source.read_bytes(), out.read_bytes()
        before, after = exif._split_bytes(data_in, "in"), exif._split_bytes(data_out, "out")
        assert after.sos_offset == before.sos_offset
        assert data_out[after.sos_offset :] == data_in[before.sos_offset :]
        assert 0 < _xmp_padding(after.header) < _xmp_padding(before.header)
        back = exif.read_tags(out)
        assert back.gps_lat_deg == pytest.approx(47.25) and back.camera_yaw_deg == pytest.approx(271.5)


def test_a_frame_without_padding_to_spare_gets_a_longer_header(tmp_path: Path) -> None:
    """No room in the XMP padding: the header grows, the image data follows it byte for byte."""
    tight = without_xmp_padding(GARFIELD_FIRST.read_bytes())
    source = tmp_path / "tight.jpg"
    source.write_bytes(tight)
    exif.write_geotag(source, tmp_path / "out.jpg", _tag(lat_deg=47.25))
    written = (tmp_path / "out.jpg").read_bytes()
    assert exif._split_bytes(written, "out").sos_offset > exif._split_bytes(tight, "in").sos_offset
    assert exif.compressed_image_data(written) == exif.compressed_image_data(tight)
    assert exif.read_tags(tmp_path / "out.jpg").gps_lat_deg == pytest.approx(47.25)


def test_xmp_padding_gives_and_takes_whitespace_only() -> None:
    from acquisition import jpeg_meta

    packet = (
        b"http://ns.adobe.com/xap/1.0/\x00<x:xmpmeta>a</x:xmpmeta>\n" + b" " * 40 + b'<?xpacket end="w"?>'
    )
    segment = b"\xff\xe1" + (len(packet) + 2).to_bytes(2, "big") + packet
    for growth in (-17, 0, 5, 40):
        padded = jpeg_meta._padded(segment, growth)
        assert len(padded) == len(segment) - growth
        assert int.from_bytes(padded[2:4], "big") == len(padded) - 2
        assert padded[4:].replace(b" ", b"") == segment[4:].replace(b" ", b"")
    assert jpeg_meta._padded(segment, 42) == segment  # 41 bytes of whitespace: not enough


def test_a_position_alone_also_keeps_the_image_data_in_place(tmp_path: Path) -> None:
    """No XMP property to change (a position without attitude on a frame without Pix4D or DJI
    tags): the padding still absorbs the new GPS directory."""
    source = tmp_path / "plain.jpg"
    make_jpeg(source, xmp={"Xmp.xmp.CreatorTool": "test"})
    data = source.read_bytes()
    # exiv2 writes its XMP with 2 KiB or more of padding
    assert _xmp_padding(exif._split_bytes(data, "in").header) > 500
    exif.write_geotag(source, tmp_path / "out.jpg", exif.GeoTag(lat_deg=1.5, lon_deg=2.5))
    written = (tmp_path / "out.jpg").read_bytes()
    assert exif._split_bytes(written, "out").sos_offset == exif._split_bytes(data, "in").sos_offset
    assert exif.read_tags(tmp_path / "out.jpg").gps_lon_deg == pytest.approx(2.5)


# ---------------------------------------------------------------------------- XMP read from its bytes


def _garfield_xmp_payload() -> bytes:
    from acquisition import jpeg_meta

    header = exif._split_bytes(GARFIELD_FIRST.read_bytes(), "garfield").header
    (start, end) = jpeg_meta._find(header, jpeg_meta.segments(header), jpeg_meta.XMP_ID)[0]
    return header[start + 4 : end]


def _map_or_error(read):  # type: ignore[no-untyped-def]
    from acquisition import jpeg_meta

    try:
        return read()
    except (jpeg_meta.UnsupportedHeaderError, UnicodeDecodeError):
        return "error"


_EDGES = [
    b"",
    b" \r\n\t",
    b"\x0b\x0c",
    b"\x1c",  # white space to str.strip, not to bytes.strip
    "\u00a0".encode(),
    b"\xef\xbb\xbf",
    b"<?xml version='1.0' encoding='ISO-8859-1'?>",
    b"<?xml version='1.0'?>",
    b"\xe9",  # Latin-1, not UTF-8
    b"\xed\xa0\x80",  # a UTF-16 surrogate in UTF-8 form
    b"\xc0\xaf",  # an overlong form
    b"&#xA;",
    b"&amp;",
]


@settings(max_examples=300, deadline=None)
@given(
    head=st.sampled_from(_EDGES),
    tail=st.sampled_from(_EDGES),
    inserts=st.lists(st.tuples(st.floats(0.0, 1.0), st.sampled_from(_EDGES)), max_size=3),
    in_values=st.booleans(),
)
@example(head=_EDGES[6], tail=b"", inserts=[(0.5, b"\xe9")], in_values=True)  # Latin-1, declared
@example(head=b"", tail=b"\x1c", inserts=[], in_values=False)
@example(head="\u00a0".encode(), tail=b"", inserts=[], in_values=False)
def test_xmp_read_from_bytes_is_the_decoded_packets_read(
    head: bytes, tail: bytes, inserts: list[tuple[float, bytes]], in_values: bool
) -> None:
    """payload_xmp_map parses the segment's bytes without decoding them into a string and back:
    whatever the bytes (white space str.strip removes and bytes.strip does not, a byte-order
    mark, an XML declaration naming another encoding, bytes that are not UTF-8, anywhere or
    inside attribute values), it gives what reading the decoded packet gives (the map, or an
    error either way)."""
    import re

    from acquisition import jpeg_meta

    packet = _garfield_xmp_payload()[len(jpeg_meta.XMP_ID) :]
    values = [m.end() for m in re.finditer(rb'="', packet)]
    for where, piece in sorted(inserts, reverse=True):
        at = values[int(where * (len(values) - 1))] if in_values else int(where * len(packet))
        packet = packet[:at] + piece + packet[at:]
    packet = head + packet + tail
    payload = jpeg_meta.XMP_ID + packet
    fast = _map_or_error(lambda: jpeg_meta.payload_xmp_map(payload))
    decoded = _map_or_error(lambda: jpeg_meta.xmp_map(packet.decode("utf-8")))
    assert fast == decoded


def test_a_real_xmp_packet_is_read_without_decoding_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """A real packet (Sequoia: it begins with a byte-order mark, which makes its decoded text two
    bytes a character) is parsed from its bytes, and read as exiv2 reads it."""
    from acquisition import jpeg_meta

    payload = _garfield_xmp_payload()
    with monkeypatch.context() as patched:
        patched.setattr(jpeg_meta, "_packet_text", lambda payload: pytest.fail("decoded"))
        read = jpeg_meta.payload_xmp_map(payload)
    image = pyexiv2.Image(str(GARFIELD_FIRST))
    try:
        exiv2 = image.read_xmp()
    finally:
        image.close()
    assert read and all(exiv2[key] == value for key, value in read.items())
