# The files of web/ that every `ddhgs report` carries, as
# "NAME=SOURCE" pairs: NAME is "index.html" (the page) or a file name under
# REPORT/assets/, SOURCE a path under web/. Read by the top-level
# CMakeLists.txt, which hands them to cmake/embed.cmake (the generator).
set(DDHGS_REPORT_ASSETS
    "index.html=report/index.html"
    "report.js=report/report.js"
    "report.css=report/report.css"
    "splat_view.js=report/splat_view.js"
    "playcanvas.min.js=vendor/playcanvas-2.23.3/playcanvas.min.js"
    "playcanvas.LICENSE.txt=vendor/playcanvas-2.23.3/LICENSE"
    "uPlot.iife.min.js=vendor/uplot-1.6.32/uPlot.iife.min.js"
    "uPlot.min.css=vendor/uplot-1.6.32/uPlot.min.css"
    "uPlot.LICENSE.txt=vendor/uplot-1.6.32/LICENSE")
