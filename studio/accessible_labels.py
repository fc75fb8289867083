"""Accessible names for viser's text fields.

viser 1.1.1 draws a field's label as ``<label for=UUID>`` but its text input (unlike its dropdowns and
number fields) does not carry ``id=UUID``, so a screen reader (or Playwright's ``get_by_label``) finds
no name for *New name*, *Import path*, …. Until viser links them, a few lines of JavaScript sent once
(and replayed to every browser that connects later) give each such input its label's text as
``aria-label``. Nothing else changes: the studio's widgets stay viser's.
"""

from __future__ import annotations

import viser
from viser import _messages

LABEL_SHIM_JS = """
(() => {
  if (window.__motionStudioLabels) return;
  window.__motionStudioLabels = true;
  let queued = false;
  const fix = () => {
    queued = false;
    for (const label of document.querySelectorAll("label[for]")) {
      if (document.getElementById(label.htmlFor)) continue;  // already linked (dropdowns, numbers)
      const row = label.parentElement && label.parentElement.parentElement && label.parentElement.parentElement.parentElement;
      const input = row && row.querySelector("input, textarea");
      const name = label.textContent.trim();
      if (input && name && input.getAttribute("aria-label") !== name) input.setAttribute("aria-label", name);
    }
  };
  new MutationObserver(() => { if (!queued) { queued = true; requestAnimationFrame(fix); } })
    .observe(document.body, { childList: true, subtree: true });
  fix();
})();
"""


def label_text_fields(server: viser.ViserServer) -> None:
    """Give every labelled viser text input its label as accessible name, in every browser."""
    # viser's own channel for client-side JavaScript (it sends plotly.js this way); kept in the scene
    # serialisation, so browsers that connect later run it too.
    server.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=LABEL_SHIM_JS))
