// The book's math, rendered offline: MathJax 3 is vendored in book/src/mathjax (see its README.md),
// which mdBook copies into the built book; nothing is fetched from another host.
//
// mdBook (with `mathjax-support = false`) leaves the TeX in the HTML as the chapters write it,
// minus markdown's escapes: `\\( ... \\)` in a chapter is `\( ... \)` in the page, `\\[ ... \\]`
// is `\[ ... \]`, and `$$ ... $$` stays. Those are the delimiters set here; a single `$` is not
// one (the shell listings use it). Code (`<code>`, `<pre>`) is skipped, MathJax's default.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["$$", "$$"], ["\\[", "\\]"]],
  },
  startup: {
    ready: function () {
      MathJax.startup.defaultReady();
      // mdBook's smart punctuation turns a prime `x'` into `x’` before MathJax sees it; give
      // TeX its prime back.
      MathJax.startup.document.inputJax[0].preFilters.add(function (args) {
        args.math.math = args.math.math.replace(/\u2019/g, "'");
      });
    },
  },
  chtml: {
    // the woff-v2 fonts beside the script: mathjax/output/chtml/fonts/woff-v2
    fontURL: path_to_root + "mathjax/output/chtml/fonts/woff-v2",
  },
};
(function () {
  // `path_to_root` is set by mdBook's page template, so this works on every page and in
  // sub-directories alike.
  var script = document.createElement("script");
  script.src = path_to_root + "mathjax/tex-chtml-full.js";
  script.async = true;
  document.head.appendChild(script);
})();

// The print page (print.html) prints itself 100 ms after it loads; wait for the formulas first.
(function () {
  var printNow = window.print.bind(window);
  var tries = 0;
  window.print = function () {
    var startup = window.MathJax && window.MathJax.startup;
    if (startup && startup.promise) {
      startup.promise.then(printNow);
    } else if (tries++ < 100) {
      setTimeout(window.print, 100); // MathJax is still loading
    } else {
      printNow();
    }
  };
})();
