#pragma once

#include <regex>
#include <string>
#include <utility>
#include <vector>

namespace sdoslam::testing {

// What a browser opens for each src= and href= of `html`, read independently of the writer:
// entities undone, the fragment and query cut off, percent-escapes decoded.
inline std::vector<std::string> ReferencedFiles(const std::string& html) {
  std::vector<std::string> files;
  const std::regex attribute(R"re(\b(?:src|href)\s*=\s*"([^"]*)")re");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), attribute);
       it != std::sregex_iterator(); ++it) {
    std::string url = (*it)[1];
    for (const auto& [entity, c] : {std::pair<std::string, std::string>{"&quot;", "\""},
                                    {"&#39;", "'"},
                                    {"&lt;", "<"},
                                    {"&gt;", ">"},
                                    {"&amp;", "&"}}) {
      for (size_t at; (at = url.find(entity)) != std::string::npos;)
        url.replace(at, entity.size(), c);
    }
    url = url.substr(0, url.find_first_of("#?"));
    std::string path;
    for (size_t i = 0; i < url.size(); ++i) {
      if (url[i] == '%' && i + 2 < url.size()) {
        path += static_cast<char>(std::stoi(url.substr(i + 1, 2), nullptr, 16));
        i += 2;
      } else {
        path += url[i];
      }
    }
    files.push_back(path);
  }
  return files;
}

}  // namespace sdoslam::testing
