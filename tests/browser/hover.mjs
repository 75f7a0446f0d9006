// For tests/test_charts.py: loads a chart's SVG, or a page that embeds charts, in Debian's Chromium,
// headless, and finds in every document for every point with a tooltip (a group whose id has -tip in
// it) whether the element at its centre lies inside a group with a <title> (its own or one drawn over
// it), which the browser shows on hover.
//   node hover.mjs URL   prints {"frames": [{"url", "points", "covered": [ids showing no tooltip]}],
//                                "requests": [every URL the page asked for]}
// CHROMIUM (default /usr/bin/chromium) names the browser.
import { chromium } from "playwright-core";

const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium" });
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
  const requests = [];
  page.on("request", (request) => requests.push(request.url()));
  await page.goto(process.argv[2], { waitUntil: "load" });
  const frames = [];
  for (const frame of page.frames()) {
    const seen = await frame.evaluate(() => {
      const points = [...document.querySelectorAll("g[id*='-tip']")];
      const covered = [];
      for (const point of points) {
        window.scrollTo(0, 0);
        const box = point.getBoundingClientRect();
        window.scrollBy(box.x - 50, box.y - 50);  // the point in view: elementFromPoint sees only the viewport
        const inView = point.getBoundingClientRect();
        let hit = document.elementFromPoint(inView.x + inView.width / 2, inView.y + inView.height / 2);
        while (hit && !(hit.tagName === "g" && hit.querySelector(":scope > title"))) {
          hit = hit.parentElement;
        }
        if (!hit) covered.push(point.id);
      }
      return { points: points.length, covered };
    });
    frames.push({ url: frame.url(), ...seen });
  }
  console.log(JSON.stringify({ frames, requests }));
} finally {
  await browser.close();
}
