// Sort a table by a column when its heading (th[data-sort]) is clicked; click again to reverse.
// The first click sorts in the heading's data-first order (scores: "descending", best first).
// Cells may carry data-value (the raw number or ISO date) so formatted text sorts correctly.
// Text sorts as the reader's language orders it (Intl.Collator, which localeCompare uses:
// "Équipe" before "Team", case and accents second, "house 2" before "house 10").
"use strict";
const collator = new Intl.Collator(undefined, {numeric: true, sensitivity: "base"});
document.addEventListener("DOMContentLoaded", () => {
  for (const table of document.querySelectorAll("table.sortable")) {
    const headings = Array.from(table.tHead.rows[0].cells);
    headings.forEach((th, column) => {
      if (!th.dataset.sort) return;
      th.tabIndex = 0;
      th.classList.add("sort-key");
      const sort = () => {
        const first = th.dataset.first === "descending" ? "descending" : "ascending";
        const current = th.getAttribute("aria-sort");
        const ascending = current === null ? first === "ascending" : current !== "ascending";
        headings.forEach((h) => h.removeAttribute("aria-sort"));
        th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
        const key = (row) => {
          const cell = row.cells[column];
          const raw = cell.dataset.value ?? cell.textContent.trim();
          return th.dataset.sort === "number" ? parseFloat(raw) : raw;
        };
        const compare = th.dataset.sort === "number"
          ? (x, y) => (x < y ? -1 : x > y ? 1 : 0)
          : (x, y) => collator.compare(x, y) || (x < y ? -1 : x > y ? 1 : 0);
        const body = table.tBodies[0];
        const rows = Array.from(body.rows);
        rows.sort((a, b) => {
          const order = compare(key(a), key(b));
          return ascending ? order : -order;
        });
        rows.forEach((row) => body.appendChild(row));
      };
      th.addEventListener("click", sort);
      th.addEventListener("keydown", (event) => {
        if (event.key !== "Enter" && event.key !== " ") return;
        event.preventDefault(); // Space would scroll the page
        sort();
      });
    });
  }
});
