// The page of a report (docs/reports.md, "The page"): one self-contained HTML file with the results
// embedded, charts drawn by Vega-Lite from files copied beside it, and the points as CSV.
#pragma once

#include <string>
#include <vector>

#include "frame_output.hpp"

namespace softgi::app::report {

// index.html with `results` (results.json's content) embedded. The page loads lib/vega.min.js,
// lib/vega-lite.min.js and lib/vega-embed.min.js; when every chart has settled it sets
// data-ready="1", data-charts (charts drawn) and data-errors (script errors) on <body>, which the
// browser test reads.
std::string page_html(const Json& results);
// One row per point: the page's numbers (RFC 4180 quoting; an empty cell for null).
std::string csv_table(const Json& results);
// The files the page loads from DIR/lib/, with their licences: what the report copies from assets/web/.
const std::vector<std::string>& page_libraries();

}  // namespace softgi::app::report
