// A table wider than its box scrolls sideways inside it (div.scroll, focusable and labelled in
// the page); this adds a visible note above such a box while it overflows, so sighted readers
// know more columns are there too. Rechecked when the window is resized.
"use strict";
const NOTE = "This box scrolls sideways: more to the right →";
function markOverflow() {
  for (const box of document.querySelectorAll("div.scroll")) {
    const wide = box.scrollWidth > box.clientWidth + 1;
    const note = box.previousElementSibling;
    const hasNote = note !== null && note.classList.contains("scroll-note");
    if (wide && !hasNote) {
      const p = document.createElement("p");
      p.className = "scroll-note";
      p.textContent = NOTE;
      box.before(p);
    } else if (!wide && hasNote) {
      note.remove();
    }
  }
}
document.addEventListener("DOMContentLoaded", markOverflow);
window.addEventListener("resize", markOverflow);
