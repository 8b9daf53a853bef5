"""Independent check of a cleave MCAP recording with the PyPI `mcap` reader.

Every message must decode as JSON; /surface must carry schema foxglove.SceneUpdate with a
triangle list; /stats must have one message per step. With --expect-rest, the recorded surface
must fall, touch the ground (min z near 0) and come to rest (tiny kinetic energy at the end).
"""
import json
import sys

from mcap.reader import make_reader


def main() -> int:
    path = sys.argv[1]
    expect_rest = "--expect-rest" in sys.argv
    counts = {}
    stats = []
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            data = json.loads(message.data)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/surface":
                assert schema.name == "foxglove.SceneUpdate", schema.name
                assert schema.encoding == "jsonschema", schema.encoding
                tri = data["entities"][0]["triangles"][0]
                assert len(tri["indices"]) % 3 == 0 and len(tri["points"]) > 0
            elif channel.topic == "/stats":
                stats.append(data)
    print(f"{path}: {counts}")
    for topic in ("/surface", "/stats", "/events"):
        assert counts.get(topic, 0) > 0, f"no messages on {topic}"
    if expect_rest:
        start_z = stats[0]["surface"]["min_z"]
        lowest = min(s["surface"]["min_z"] for s in stats)
        final = stats[-1]
        print(f"min z: start {start_z:.4f} m, lowest {lowest:.4f} m, final {final['surface']['min_z']:.4f} m; "
              f"final kinetic energy {final['energy']['kinetic']:.3e} J")
        assert start_z > 0.2, "the bunny should start above the ground"
        assert abs(lowest) < 0.02, "the bunny should reach the ground"
        assert final["energy"]["kinetic"] < 1e-3, "the bunny should come to rest"
    return 0


if __name__ == "__main__":
    sys.exit(main())
