"""docs/foxglove-layout.json: the layout file a viewer imports (Foxglove and Lichtblick).

Its shape is the one both apps export and import: ``configById`` (panel id
``Type!name`` → config), a ``layout`` tree of splits whose leaves are those ids, and
``globalVariables``, ``userNodes``, ``playbackConfig``. Every topic and service it names is
one the server gives a robot named ``robot`` (``galileo foxglove``'s default name;
``/robot/map`` one on http://).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema

from galileo_async.foxglove.schemas import SERVICE_REQUESTS

LAYOUT = Path(__file__).resolve().parents[2] / "docs" / "foxglove-layout.json"
TOPICS = ("pose", "tf", "status", "link", "scene", "events", "map", "map_info")
#: The panel types of the 3D, Image, Log, Raw Messages and Service Call panels in both apps.
PANEL_TYPES = {"3D", "Image", "RosOut", "RawMessages", "CallService"}


def leaves(node: Any) -> list[str]:
    if isinstance(node, str):
        return [node]
    assert set(node) == {"first", "second", "direction", "splitPercentage"}, node
    assert node["direction"] in ("row", "column")
    assert 0 < node["splitPercentage"] < 100
    return leaves(node["first"]) + leaves(node["second"])


def test_the_layout_has_the_shape_the_apps_import() -> None:
    layout = json.loads(LAYOUT.read_text(encoding="utf-8"))
    assert set(layout) == {"configById", "layout", "globalVariables", "userNodes", "playbackConfig"}
    panels = leaves(layout["layout"])
    assert sorted(panels) == sorted(layout["configById"])
    assert {panel.split("!")[0] for panel in panels} == PANEL_TYPES


def test_every_topic_and_service_of_the_layout_is_served() -> None:
    configs = json.loads(LAYOUT.read_text(encoding="utf-8"))["configById"]
    topics = {f"/robot/{topic}" for topic in TOPICS}
    for panel, config in configs.items():
        kind = panel.split("!")[0]
        if kind == "3D":
            assert config["followTf"] == "map"
            assert set(config["topics"]) <= topics
        elif kind == "Image":
            assert config["imageMode"]["imageTopic"] == "/robot/map"
        elif kind == "RosOut":
            assert config["topicToRender"] == "/robot/events"
        elif kind == "RawMessages":
            assert config["topicPath"] in topics
        else:
            name = config["serviceName"].removeprefix("/robot/")
            request = json.loads(config["requestPayload"])
            jsonschema.validate(request, SERVICE_REQUESTS[name])
