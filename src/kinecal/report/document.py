"""Write a report as HTML or PDF: the same document, chosen by the file name's suffix.

A ``.pdf`` path is rendered from the report's HTML by WeasyPrint (the ``pdf`` extra:
``pip install 'kinecal[pdf]'``), which lays out the same tables, figures and print CSS
(A4 pages, numbered, the record in the footer) as the browser shows; any other suffix
writes the HTML itself. Both are written atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinecal._files import write_bytes_atomic, write_text_atomic
from kinecal.errors import InputError

__all__ = ["check_report_path", "html_to_pdf", "is_pdf", "write_report"]

_MISSING = ("PDF reports need WeasyPrint: pip install 'kinecal[pdf]' (it uses the system's "
            "Pango library), or write the report as .html")


def is_pdf(path: str | Path) -> bool:
    """True when `path` names a PDF report (suffix ``.pdf``, any case)."""
    return Path(path).suffix.lower() == ".pdf"


def _weasyprint() -> Any:
    from PIL import ImageFile

    # WeasyPrint sets Pillow's process-wide LOAD_TRUNCATED_IMAGES when imported: every
    # later check of an image file cut short (kinecal.vision.image_files) would pass it
    truncated = ImageFile.LOAD_TRUNCATED_IMAGES
    try:
        import weasyprint
    except (ImportError, OSError) as exc:  # OSError: the Pango library is missing
        raise InputError(f"{_MISSING} ({type(exc).__name__}: {exc})".split("\n")[0],
                         option="--report") from None
    finally:
        ImageFile.LOAD_TRUNCATED_IMAGES = truncated
    return weasyprint


def check_report_path(path: str | Path | None, option: str = "--report") -> None:
    """Refuse, before any work, a PDF report when WeasyPrint cannot be loaded."""
    if path is not None and is_pdf(path):
        try:
            _weasyprint()
        except InputError as exc:
            raise InputError(exc.message, option=option) from None


def html_to_pdf(doc: str) -> bytes:
    """PDF bytes of a self-contained HTML document (no file or network access: every
    figure is a ``data:`` URI)."""
    weasyprint = _weasyprint()
    if hasattr(weasyprint, "URLFetcher"):  # WeasyPrint >= 66
        fetcher: Any = weasyprint.URLFetcher(allowed_protocols=("data",))
    else:
        def fetcher(url: str, *args: Any, **kwargs: Any) -> Any:
            if not url.startswith("data:"):
                raise ValueError(f"report resources are embedded; not fetching {url[:60]}")
            return weasyprint.default_url_fetcher(url, *args, **kwargs)

    import logging

    # WeasyPrint logs every CSS property it does not know at WARNING level on its own logger
    logging.getLogger("weasyprint").setLevel(logging.ERROR)
    return weasyprint.HTML(string=doc, url_fetcher=fetcher).write_pdf()


def write_report(path: str | Path, doc: str) -> Path:
    """Write the HTML document `doc` to `path`, as PDF when the suffix is ``.pdf``;
    returns the path."""
    path = Path(path)
    if is_pdf(path):
        write_bytes_atomic(path, html_to_pdf(doc))
    else:
        write_text_atomic(path, doc)
    return path
