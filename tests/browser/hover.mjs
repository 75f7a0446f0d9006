// For tests/test_charts.py: loads a chart's SVG in Debian's Chromium, headless, and finds for every point
// with a tooltip (a group whose id ends in -tipN) whether the element at its centre lies inside a group
// with a <title>, which the browser shows on hover.
//   node hover.mjs URL   prints {"points": n, "covered": [ids whose centre shows no tooltip], "requests": [...]}
// CHROMIUM (default /usr/bin/chromium) names the browser.
import { chromium } from "playwright-core";

const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium" });
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
  const requests = [];
  page.on("request", (request) => requests.push(request.url()));
  await page.goto(process.argv[2]);
  const seen = await page.evaluate(() => {
    const points = [...document.querySelectorAll("g[id*='-tip']")];
    const covered = [];
    for (const point of points) {
      const box = point.getBoundingClientRect();
      window.scrollTo(0, 0);
      window.scrollBy(box.x - 50, box.y - 50);  // the point in view: elementFromPoint sees only the viewport
      const inView = point.getBoundingClientRect();
      let hit = document.elementFromPoint(inView.x + inView.width / 2, inView.y + inView.height / 2);
      while (hit && !(hit.id && hit.id.includes("-tip") && hit.querySelector(":scope > title"))) hit = hit.parentElement;
      if (!hit) covered.push(point.id);
    }
    return { points: points.length, covered };
  });
  console.log(JSON.stringify({ ...seen, requests }));
} finally {
  await browser.close();
}
