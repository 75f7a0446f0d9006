// Drives the live view (harness view) in Debian's Chromium, headless, for tests/test_view.py.
//   node drive.mjs check URL            prints the text of <pre id="check"> once the page wrote it
//   node drive.mjs session URL PLAN.json  a person's session, paused: PLAN is a list of actions;
//                                          prints what they saw as JSON, by label
//   node drive.mjs shot URL FILE.png S    lets the scene run S seconds, then a screenshot
// Actions: {"set": [component, setting, value]} (a method select or a step field),
//   {"drag": [component, xOutput, yOutput, [x, y]]} (the mouse takes that point to x, y metres),
//   {"click": selector} (a button), {"step": n} (the Step button n times), {"snapshot": label},
//   {"start": [label, component]},
//   {"problem": label} (the page's problem line), {"screenshot": file}
// CHROMIUM (default /usr/bin/chromium) names the browser.
import { readFileSync } from "node:fs";
import { chromium } from "playwright-core";

const [mode, url, extra, seconds] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium" });
const problems = [];
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
  page.on("pageerror", (error) => problems.push(String(error)));
  page.on("console", (message) => { if (message.type() === "error") problems.push(message.text()); });
  page.on("request", (request) => {
    if (!/^(file|data|blob):/.test(request.url()) && !request.url().startsWith(new URL(url).origin)) {
      problems.push(`network request: ${request.url()}`);
    }
  });
  await page.goto(url);
  if (mode === "check") {
    await page.waitForSelector("#check[data-done]", { state: "attached", timeout: 600000 });
    const result = JSON.parse(await page.textContent("#check"));
    console.log(JSON.stringify({ ...result, problems }));
  } else if (mode === "session") {
    await page.waitForFunction(() => window.pendulumView !== undefined || document.getElementById("problem").textContent);
    await page.evaluate(() => window.pendulumView.pause());
    const seen = {};
    for (const action of JSON.parse(readFileSync(extra, "utf8"))) {
      if (action.set) {
        const [component, setting, value] = action.set;
        const selector = `[data-component="${component}"][data-setting="${setting}"]`;
        if (setting === "solver") await page.selectOption(selector, { label: value });
        else {
          await page.fill(selector, String(value));
          await page.dispatchEvent(selector, "change");
        }
      } else if (action.drag) {
        const [component, xName, yName, to] = action.drag;
        const unit = await page.evaluate(() => window.pendulumView.snapshot());
        const point = [unit.components[component][xName], unit.components[component][yName]];
        const from = await page.evaluate(([name, p]) => window.pendulumView.pagePoint(name, p), [component, point]);
        const target = await page.evaluate(([name, p]) => window.pendulumView.pagePoint(name, p), [component, to]);
        await page.mouse.move(...from);
        await page.mouse.down();
        await page.mouse.move((from[0] + target[0]) / 2, (from[1] + target[1]) / 2, { steps: 3 });
        await page.mouse.move(...target, { steps: 3 });
        // the metres per pixel the drop was made at, before the view frames the new start
        seen.metres_per_pixel = 1 / await page.evaluate(() => window.pendulumView.scale());
        await page.mouse.up();
      } else if (action.click) {
        await page.click(action.click);
      } else if (action.step) {
        for (let k = 0; k < action.step; k++) await page.click("#step");
      } else if (action.snapshot) {
        seen[action.snapshot] = await page.evaluate(() => window.pendulumView.snapshot());
      } else if (action.start) {
        const [label, component] = action.start;
        seen[label] = await page.evaluate((name) => window.pendulumView.master.unit(name).start, component);
      } else if (action.problem) {
        seen[action.problem] = await page.textContent("#problem");
      } else if (action.screenshot) {
        await page.screenshot({ path: action.screenshot });
      }
    }
    console.log(JSON.stringify({ ...seen, problems }));
  } else if (mode === "shot") {
    await page.waitForFunction(() => window.pendulumView !== undefined || document.getElementById("problem").textContent);
    await page.waitForTimeout(1000 * Number(seconds));
    await page.screenshot({ path: extra });
    const problem = await page.textContent("#problem");
    const time = await page.evaluate(() => window.pendulumView?.master.time ?? null);
    console.log(JSON.stringify({ time, problem, problems }));
  } else {
    throw new Error(`mode ${mode}: choose check, session or shot`);
  }
} finally {
  await browser.close();
}
