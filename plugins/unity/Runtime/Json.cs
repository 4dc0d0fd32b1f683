// Json.cs -- a minimal JSON reader (RFC 8259) for the glTF JSON chunk: objects become
// Dictionary<string, object>, arrays List<object>, numbers double, strings string, true/false
// bool, null null. No engine reference (Unity's JsonUtility cannot read glTF's free-form
// extensions), no reflection.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.Text;

namespace Gsverse.MeshAnchor
{
    public static class Json
    {
        /// <summary>The value of a JSON text; FormatException on malformed input.</summary>
        public static object Parse(string text)
        {
            int pos = 0;
            object value = ReadValue(text, ref pos, 0);
            SkipSpace(text, ref pos);
            if (pos != text.Length) throw new FormatException("JSON: text after the value at " + pos);
            return value;
        }

        const int MaxDepth = 256;   // nesting deeper than any glTF document needs

        static void SkipSpace(string s, ref int p)
        {
            while (p < s.Length && (s[p] == ' ' || s[p] == '\t' || s[p] == '\n' || s[p] == '\r')) p++;
        }

        static object ReadValue(string s, ref int p, int depth)
        {
            if (depth > MaxDepth) throw new FormatException("JSON: nested too deeply");
            SkipSpace(s, ref p);
            if (p >= s.Length) throw new FormatException("JSON: unexpected end");
            char c = s[p];
            if (c == '{')
            {
                var obj = new Dictionary<string, object>();
                p++;
                SkipSpace(s, ref p);
                if (p < s.Length && s[p] == '}') { p++; return obj; }
                while (true)
                {
                    SkipSpace(s, ref p);
                    if (p >= s.Length || s[p] != '"') throw new FormatException("JSON: expected a key at " + p);
                    string key = ReadString(s, ref p);
                    SkipSpace(s, ref p);
                    if (p >= s.Length || s[p] != ':') throw new FormatException("JSON: expected ':' at " + p);
                    p++;
                    obj[key] = ReadValue(s, ref p, depth + 1);
                    SkipSpace(s, ref p);
                    if (p < s.Length && s[p] == ',') { p++; continue; }
                    if (p < s.Length && s[p] == '}') { p++; return obj; }
                    throw new FormatException("JSON: expected ',' or '}' at " + p);
                }
            }
            if (c == '[')
            {
                var list = new List<object>();
                p++;
                SkipSpace(s, ref p);
                if (p < s.Length && s[p] == ']') { p++; return list; }
                while (true)
                {
                    list.Add(ReadValue(s, ref p, depth + 1));
                    SkipSpace(s, ref p);
                    if (p < s.Length && s[p] == ',') { p++; continue; }
                    if (p < s.Length && s[p] == ']') { p++; return list; }
                    throw new FormatException("JSON: expected ',' or ']' at " + p);
                }
            }
            if (c == '"') return ReadString(s, ref p);
            if (Literal(s, ref p, "true")) return true;
            if (Literal(s, ref p, "false")) return false;
            if (Literal(s, ref p, "null")) return null;
            int start = p;
            if (p < s.Length && s[p] == '-') p++;
            while (p < s.Length && (char.IsDigit(s[p]) || s[p] == '.' || s[p] == 'e' || s[p] == 'E'
                                    || s[p] == '+' || s[p] == '-')) p++;
            double d;
            if (p == start || !double.TryParse(s.Substring(start, p - start), NumberStyles.Float,
                                               CultureInfo.InvariantCulture, out d))
                throw new FormatException("JSON: bad value at " + start);
            return d;
        }

        static bool Literal(string s, ref int p, string word)
        {
            if (string.CompareOrdinal(s, p, word, 0, word.Length) != 0) return false;
            p += word.Length;
            return true;
        }

        static string ReadString(string s, ref int p)
        {
            var sb = new StringBuilder();
            p++;   // the opening quote
            while (p < s.Length)
            {
                char c = s[p++];
                if (c == '"') return sb.ToString();
                if (c != '\\') { sb.Append(c); continue; }
                if (p >= s.Length) break;
                char e = s[p++];
                switch (e)
                {
                    case '"': sb.Append('"'); break;
                    case '\\': sb.Append('\\'); break;
                    case '/': sb.Append('/'); break;
                    case 'b': sb.Append('\b'); break;
                    case 'f': sb.Append('\f'); break;
                    case 'n': sb.Append('\n'); break;
                    case 'r': sb.Append('\r'); break;
                    case 't': sb.Append('\t'); break;
                    case 'u':
                        if (p + 4 > s.Length) throw new FormatException("JSON: bad \\u escape");
                        sb.Append((char)int.Parse(s.Substring(p, 4), NumberStyles.HexNumber,
                                                  CultureInfo.InvariantCulture));
                        p += 4;
                        break;
                    default: throw new FormatException("JSON: bad escape at " + p);
                }
            }
            throw new FormatException("JSON: unterminated string");
        }
    }
}
