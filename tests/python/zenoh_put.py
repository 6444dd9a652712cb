"""An eclipse-zenoh client of a towernav fleet, as protocol/README.md shows
one: it connects to ENDPOINT (with a node's credentials folder for a secured
fleet), puts TEXT on each KEY, and says whether it had a link.

    python3 zenoh_put.py ENDPOINT [--credentials DIR] KEY=TEXT...
"""

import argparse
import json
import sys
import time

import zenoh


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("endpoint")
    p.add_argument("--credentials")
    p.add_argument("puts", nargs="+")
    args = p.parse_args()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([args.endpoint]))
    # Give up quickly when nobody will have us.
    conf.insert_json5("connect/timeout_ms", "3000")
    if args.credentials:
        d = args.credentials.rstrip("/") + "/"
        for key, value in [
            ("root_ca_certificate", "ca.pem"),
            ("connect_certificate", "node.pem"),
            ("connect_private_key", "node.key"),
        ]:
            conf.insert_json5(f"transport/link/tls/{key}", json.dumps(d + value))
        conf.insert_json5("transport/link/tls/enable_mtls", "true")
    try:
        session = zenoh.open(conf)
    except Exception as e:  # noqa: BLE001 - any refusal is the answer
        print(f"no link: {e}")
        return 0
    linked = len(list(session.info.routers_zid())) > 0
    print("linked" if linked else "no link")
    time.sleep(0.3)
    for put in args.puts:
        key, _, text = put.partition("=")
        session.put(key, text)
    time.sleep(0.5)
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
