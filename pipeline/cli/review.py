"""`dance3d review`: the annotators' local web page (tracks and trim)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_review(sub: argparse._SubParsersAction) -> None:
    review = sub.add_parser("review", help="a local web page for trimming videos and cleaning tracks",
                            description="Serve the review page. Tracks mode (/): watch each segment's QC video, "
                                        "edit its track manifest on a timeline and save it (checked like "
                                        "`dance3d manifests check`). Trim mode (/trim): play each downloaded "
                                        "video with its shots and proposed dance segments, and set, split, add "
                                        "or delete its rows of annotations/segments.csv with the same keys "
                                        "(checked as the trim stage checks). Loopback only unless --host says "
                                        "otherwise.")
    review.add_argument("--port", type=int, default=8765, help="the local port to serve the page on (default 8765)")
    review.add_argument("--host", default="127.0.0.1",
                        help="interface to listen on (default: loopback only). Any other (e.g. 0.0.0.0 for a "
                             "team on a lab server) requires a token, printed in the start-up addresses "
                             "(or taken from $DANCE3D_REVIEW_TOKEN)")
    review.add_argument("--token", action="store_true",
                        help="require the token on loopback too (always required elsewhere)")
    review.add_argument("--mode", choices=("tracks", "trim"), default="tracks",
                        help="the page to print first (both are served)")
    review.set_defaults(handler=serve_review)


def serve_review(root: Path, args: argparse.Namespace) -> int:
    from pipeline.annotate.commands import proposal_options
    from pipeline.annotate.review.access import choose_token
    from pipeline.annotate.review.server import ReviewApp, serve
    from pipeline.core.params import load_params, stage_params

    params = load_params(root / "params.yaml")
    token = choose_token(args.host, args.token)
    app = ReviewApp(root, proposal_options(params), float(stage_params(params, "clean").get("min_clip_seconds", 2.0)),
                    token)
    server = serve(app, args.host, args.port)
    host = f"[{args.host}]" if ":" in args.host else args.host
    base = f"http://{host}:{server.server_address[1]}"
    login = f"?token={token}" if token else ""
    pages = [f"{base}/trim{login}  (trim videos)", f"{base}/{login}  (clean tracks)"]
    print("dance3d review: " + "\n                ".join(pages if args.mode == "trim" else pages[::-1])
          + ("\n(the token is needed once per browser; share these addresses only with your annotators)"
             if token else "") + "\n(Ctrl+C to stop)", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
    return 0
