// The site's search scorer (html_search_scorer): Sphinx's own weights, and the public names
// first. An object named allsky.NAME is what `import allsky` gives (allsky.fly,
// allsky.Flight ...); allsky.Class.member its members. The modules' own pages (allsky.apps.
// api.fly, the same function documented where it is defined) come after them.
var Scorer = {
  score: (result) => {
    const [, title, , , score, , kind] = result;
    if (kind !== "object") return score;
    const parts = title.split(".");
    if (parts[0] !== "allsky") return score;
    if (parts.length === 2) return score + 30;
    if (parts.length === 3 && /^[A-Z]/.test(parts[1])) return score + 15;
    return score;
  },
  objNameMatch: 11,
  objPartialMatch: 6,
  objPrio: { 0: 15, 1: 5, 2: -5 },
  objPrioDefault: 0,
  title: 15,
  partialTitle: 7,
  term: 5,
  partialTerm: 2,
};
