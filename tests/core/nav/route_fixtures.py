"""GeoJSON route graph features for the route tests."""

from __future__ import annotations


def node(i: int, x: float, y: float, **props: object) -> dict:
    return {"type": "Feature", "properties": {"id": i, **props}, "geometry": {"type": "Point", "coordinates": [x, y]}}


def edge(i: int, s: int, e: int, **props: object) -> dict:
    return {
        "type": "Feature",
        "properties": {"id": i, "startid": s, "endid": e, **props},
        "geometry": {"type": "MultiLineString", "coordinates": [[[0, 0], [1, 1]]]},
    }


def graph(*features: dict) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}
