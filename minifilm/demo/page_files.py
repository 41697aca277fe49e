"""The demo page and its files, as the server sends them: read once, served from memory.

Only the exact paths of ``Site.files`` exist; every other path is 404, so no request can reach
any other file (``/../``, ``%2e%2e``, absolute paths, backslashes are just unknown paths). The
page is ``assets/demo.html``; its scripts are ``assets/demo.js`` (the page's own logic) and the
viewer's ``scene.js`` (stage, floor, skeletons, orbit camera: the motion player's code, shared),
its ``mannequin.js`` (the shaded body) and vendored three.js, found through an import map. Every response forbids anything from
elsewhere (``Content-Security-Policy``: scripts, styles and connections from this server only;
the inline import map is allowed by its hash), so the page makes no request off this machine.
"""
from __future__ import annotations

import base64
import hashlib
import json
from pathlib import Path
from typing import Dict, Optional, Tuple

from minifilm.viewer.html import MANNEQUIN_JS, SCENE_JS, THREE_JS, THREE_VERSION

HERE = Path(__file__).resolve().parent / "assets"

IMPORT_MAP = json.dumps({"imports": {"three": "/three.module.min.js", "minifilm-scene": "/scene.js",
                                     "minifilm-mannequin": "/mannequin.js"}})


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


class Site:
    """path -> (body bytes, content type) for every file of the page, and the headers they go with."""

    def __init__(self, title: str = "minifilm demo"):
        html = (HERE / "demo.html").read_text(encoding="utf-8")
        html = html.replace("{{TITLE}}", _escape(title)).replace("{{THREE_VERSION}}", THREE_VERSION)
        html = html.replace("{{IMPORT_MAP}}", IMPORT_MAP)
        digest = base64.b64encode(hashlib.sha256(IMPORT_MAP.encode("utf-8")).digest()).decode("ascii")
        self.csp = ("default-src 'none'; "
                    f"script-src 'self' 'sha256-{digest}'; style-src 'self'; img-src 'self' data:; "
                    "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")
        js, css = "text/javascript; charset=utf-8", "text/css; charset=utf-8"
        self.files: Dict[str, Tuple[bytes, str]] = {
            "/": (html.encode("utf-8"), "text/html; charset=utf-8"),
            "/demo.js": ((HERE / "demo.js").read_bytes(), js),
            "/demo.css": ((HERE / "demo.css").read_bytes(), css),
            "/scene.js": (SCENE_JS.read_bytes(), js),
            "/mannequin.js": (MANNEQUIN_JS.read_bytes(), js),
            "/three.module.min.js": (THREE_JS.read_bytes(), js),
        }

    def get(self, path: str) -> Optional[Tuple[bytes, str]]:
        """The file at exactly ``path`` (query string removed), or None."""
        return self.files.get(path.split("?", 1)[0])

    def headers(self, content_type: str, length: int) -> list:
        """Response headers: no caching (a restarted server may serve another version), no sniffing,
        no referrer, and the page's policy."""
        return [("Content-Type", content_type), ("Content-Length", str(length)), ("Cache-Control", "no-store"),
                ("X-Content-Type-Options", "nosniff"), ("Referrer-Policy", "no-referrer"),
                ("Content-Security-Policy", self.csp)]
