"""Reading a rendered report page back as a person sees it: its title, its verdict, the key figures
(value, goal, pass mark) and the other fields, by their report.json keys."""

import html
import re


def title(page: str) -> str:
    return html.unescape(re.search(r"<h1>(.*?)</h1>", page).group(1))


def verdict(page: str) -> tuple[str, str]:
    """(``ok``, ``fail`` or ``info``; the verdict's text)."""
    kind, text = re.search(r'<div class="verdict (\w+)">(.*?)</div>', page).groups()
    return kind, html.unescape(text)


def key_figures(page: str) -> dict[str, tuple[str, str, bool | None]]:
    """report.json key → (value, goal, pass mark) of each key figure."""
    rows = re.findall(r'<tr><td>[^<]*<span class="key">([^<]+)</span></td><td class="num">([^<]*)</td>'
                      r"<td>([^<]*)</td><td>(.*?)</td></tr>", page)
    mark = {"": None, '<span class="pass">✓</span>': True, '<span class="miss">✗</span>': False}
    return {key: (html.unescape(value), html.unescape(goal), mark[m]) for key, value, goal, m in rows}


def fields(page: str) -> dict[str, str]:
    """report.json key → the HTML of its value, for the fields below the first screen."""
    rest = page[page.index("<h2>Every other field</h2>"):]
    return dict(re.findall(r'<tr><td>[^<]*<span class="key">([^<]+)</span></td><td>(.*?)</td></tr>(?=<tr><td>[^<]*'
                           r'<span class="key">|</table></div>)', rest, flags=re.S))


def command(page: str) -> str | None:
    found = re.search(r'<code class="cmd">(.*?)</code>', page)
    return None if found is None else html.unescape(found.group(1))
