"""Local frames (planner.geo): the UTM zone of an area against PROJ's own database."""

from __future__ import annotations

import functools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.errors import AreaError
from planner.geo import LocalFrame


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    lon=st.floats(-179.9, 179.9).filter(lambda x: abs((x + 180.0) / 6.0 - round((x + 180.0) / 6.0)) > 1e-4),
    lat=st.floats(-79.9, 83.9).filter(lambda y: abs(y) > 1e-6),
)
def test_utm_zone_is_the_one_proj_database_names(lon: float, lat: float) -> None:
    """LocalFrame.utm_for computes the zone; PROJ's database (the WGS 84 UTM CRSs and their areas
    of use, read once) is the independent oracle, away from zone borders where both zones are right."""
    codes = {code for code, (w, s, e, n) in _utm_areas_of_use().items() if w <= lon <= e and s <= lat <= n}
    assert LocalFrame.utm_for(lon, lat).epsg in codes


@functools.cache
def _utm_areas_of_use() -> dict[int, tuple[float, float, float, float]]:
    """EPSG code -> (west, south, east, north) of every WGS 84 / UTM zone NN N|S CRS in PROJ's database."""
    from pyproj.database import query_utm_crs_info

    return {
        int(i.code): (i.area_of_use.west, i.area_of_use.south, i.area_of_use.east, i.area_of_use.north)
        for i in query_utm_crs_info(datum_name="WGS 84")
        if i.code.startswith(("326", "327")) and i.area_of_use is not None
    }


@pytest.mark.parametrize(("lon", "lat"), [(0.0, 84.5), (10.0, -80.5), (181.0, 10.0)])
def test_no_utm_zone_beyond_its_limits(lon: float, lat: float) -> None:
    with pytest.raises(AreaError, match="no UTM zone covers"):
        LocalFrame.utm_for(lon, lat)
