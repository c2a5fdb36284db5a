// Typeset the equations (pymdownx.arithmatex, generic mode) with the KaTeX copy shipped in
// docs/javascripts/katex (0.19.1, MIT): no network needed to read the pages.
document$.subscribe(({ body }) => {
  renderMathInElement(body, {
    delimiters: [
      { left: "$$", right: "$$", display: true },
      { left: "\\[", right: "\\]", display: true },
      { left: "\\(", right: "\\)", display: false },
    ],
    throwOnError: false,
  });
});
